"""External force schedules applied through `xfrc_applied`, and periodic velocity pushes.

A schedule draws a horizontal force (uniform magnitude, uniform direction) at the start of each period
and holds it for `duration_steps` control steps (its hold time); in between, no force acts. `duration ==
period` is a continuous disturbance, a short duration an impulse. The same force vector acts on each body of
the target group ("centroid": the root body; "hands" and "feet": each of the two bodies), at the body's centre
of mass; a schedule with `per_body` draws each body's magnitude and direction on its own instead.
A `ForceCycle` takes turns between schedules (targets and kinds of force) within an episode, starting
each episode at one of its `start_phases`.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import NamedTuple

import numpy as np

from zerith_gym.core.arrays import namespace

FORCE_TARGET_NAMES = ("centroid", "hands", "feet")
"""Where a force can act: the root body, each hand, each foot (`RobotSpec.force_bodies` names the bodies)."""
TARGET_INDEX = {name: index for index, name in enumerate(FORCE_TARGET_NAMES)}
"""Index of each target in `FORCE_TARGET_NAMES`, as the per-step force target tables hold it."""
FORCE_DRAWS = 2
"""Uniform numbers in [0, 1) consumed by one force draw: magnitude and direction."""
PUSH_DRAWS = 2


@dataclass(frozen=True)
class ForceSchedule:
    """When and how strong the external force is, in control steps (50 per second)."""

    target: str = "centroid"
    magnitude: tuple[float, float] = (0.0, 0.0)
    """Uniform range of the force magnitude (N)."""
    period_steps: int = 5
    duration_steps: int = 5
    start_step: int = 0
    direction: float | None = None
    """Direction (rad, world frame, from +x towards +y) of every force drawn; None: uniform."""
    per_body: bool = False
    """False: one force vector is drawn and acts on every body of the target group (both hands, both feet);
    True: each body of the group draws its own magnitude and direction, at the same steps and from the same
    range. The same for the centroid, a group of one body."""

    def __post_init__(self) -> None:
        if self.target not in FORCE_TARGET_NAMES:
            raise ValueError(
                f"ForceSchedule target must be one of {sorted(FORCE_TARGET_NAMES)}, got {self.target!r}"
            )
        if not 0 < self.duration_steps <= self.period_steps:
            raise ValueError("ForceSchedule needs 0 < duration_steps <= period_steps")

    @property
    def active(self) -> bool:
        return self.magnitude[1] > 0.0

    @property
    def targets(self) -> tuple[str, ...]:
        """The targets it pushes (none if it never pushes)."""
        return (self.target,) if self.active else ()

    @property
    def start_offsets(self) -> tuple[int, ...]:
        """The steps of its table an episode may start at: the first."""
        return (0,)

    def scaled(self, scale: float) -> ForceSchedule:
        """This schedule with its magnitudes multiplied by `scale`."""
        return replace(self, magnitude=(scale * self.magnitude[0], scale * self.magnitude[1]))

    def table(self, num_steps: int) -> ForceTable:
        """This schedule over control steps 0..num_steps-1."""
        draw, on = schedule_table(self, num_steps)
        return ForceTable(
            draw, on, np.tile(np.asarray(self.magnitude, dtype=float), (num_steps, 1)),
            np.full(num_steps, TARGET_INDEX[self.target]),
            np.full(num_steps, np.nan if self.direction is None else float(self.direction)),
            np.full(num_steps, bool(self.per_body)),
        )  # fmt: skip


@dataclass(frozen=True)
class ForceCycle:
    """Schedules taking turns within an episode: `schedules[k]` acts over steps [k, k + 1) * `phase_steps`
    of the cycle's table, then the cycle starts again. Each schedule keeps its own timing in table steps
    (an impulse schedule with period 100 strikes at steps 100, 200, ... that fall in its phases).

    Each episode starts at a phase drawn uniformly from `start_phases` (the table read from that phase's
    first step on). With the default, every episode starts at phase 0, so the later phases act only on
    robots that lasted through the earlier ones: a policy that falls early trains little under them.
    """

    schedules: tuple[ForceSchedule, ...]
    phase_steps: int = 100
    start_phases: tuple[int, ...] = (0,)

    def __post_init__(self) -> None:
        if not self.schedules or not all(isinstance(s, ForceSchedule) for s in self.schedules):
            raise ValueError("ForceCycle needs one or more ForceSchedule")
        if not isinstance(self.phase_steps, int) or self.phase_steps < 1:
            raise ValueError(f"ForceCycle phase_steps must be a positive integer, got {self.phase_steps!r}")
        phases = range(len(self.schedules))
        if not self.start_phases or not all(isinstance(p, int) and p in phases for p in self.start_phases):
            raise ValueError(
                f"ForceCycle start_phases must be one or more phase indices in [0, {len(self.schedules)}), "
                f"got {self.start_phases!r}"
            )

    @property
    def start_offsets(self) -> tuple[int, ...]:
        """The steps of its table an episode may start at: the first step of each start phase."""
        return tuple(phase * self.phase_steps for phase in self.start_phases)

    @property
    def active(self) -> bool:
        return any(s.active for s in self.schedules)

    @property
    def targets(self) -> tuple[str, ...]:
        """The targets its schedules push, each once."""
        return tuple(dict.fromkeys(t for s in self.schedules for t in s.targets))

    @property
    def magnitude(self) -> tuple[float, float]:
        """The smallest and largest magnitude of any of its schedules (N)."""
        return min(s.magnitude[0] for s in self.schedules), max(s.magnitude[1] for s in self.schedules)

    def scaled(self, scale: float) -> ForceCycle:
        return replace(self, schedules=tuple(s.scaled(scale) for s in self.schedules))

    def table(self, num_steps: int) -> ForceTable:
        """The schedules' tables, each over its phases; a phase whose force acts from its first step draws
        a new one there (no force carries over from the previous phase)."""
        tables = [s.table(num_steps) for s in self.schedules]
        steps = np.arange(num_steps)
        phase = (steps // self.phase_steps) % len(self.schedules)
        table = ForceTable(*(np.stack(column)[phase, steps] for column in zip(*tables, strict=True)))
        phase_start = steps % self.phase_steps == 0
        return table._replace(draw=table.draw | (phase_start & table.on))


class ForceTable(NamedTuple):
    """A force program over an episode's control steps: what the task reads at each step."""

    draw: np.ndarray  # (steps,) bool: a new force is drawn
    on: np.ndarray  # (steps,) bool: the force acts
    magnitude: np.ndarray  # (steps, 2) N: the range a new force's magnitude is drawn from
    target: np.ndarray  # (steps,) int: the target it acts on (`TARGET_INDEX`)
    direction: np.ndarray  # (steps,) rad: a new force's direction, NaN for a uniform one
    per_body: np.ndarray  # (steps,) bool: each body of the target draws its own (`ForceSchedule.per_body`)


ForceProgram = ForceSchedule | ForceCycle
"""What a scenario's `force` can be: one schedule, or schedules taking turns."""
NO_FORCE = ForceSchedule()


def horizontal_vectors(
    uniforms: np.ndarray, magnitude: np.ndarray, direction: np.ndarray | None = None
) -> np.ndarray:
    """Vectors (n, 3) of uniform magnitude in `magnitude` and uniform horizontal direction (numpy or JAX),
    or the angle `direction` (n,) (rad) where it is not NaN."""
    xp = namespace(uniforms)
    magnitude = xp.asarray(magnitude)
    low, high = magnitude[..., 0], magnitude[..., 1]  # a range, or one per vector (n, 2)
    norm = low + (high - low) * uniforms[:, 0]
    angle = 2.0 * np.pi * uniforms[:, 1]
    if direction is not None:
        angle = xp.where(xp.isnan(direction), angle, direction)
    return xp.stack([norm * xp.cos(angle), norm * xp.sin(angle), xp.zeros_like(norm)], axis=1)


def schedule_table(schedule: ForceSchedule, num_steps: int) -> tuple[np.ndarray, np.ndarray]:
    """For control steps 0..num_steps-1: whether a new force is drawn, and whether a force acts."""
    since_start = np.arange(num_steps) - schedule.start_step
    in_period = since_start % schedule.period_steps
    started = (since_start >= 0) & schedule.active
    return started & (in_period == 0), started & (in_period < schedule.duration_steps)


def push_due(num_steps: int, interval_steps: int, magnitude: tuple[float, float]) -> np.ndarray:
    """For control steps 0..num_steps-1: whether a velocity push is given."""
    steps = np.arange(num_steps)
    return (steps > 0) & (steps % interval_steps == 0) & (magnitude[1] > 0.0)
