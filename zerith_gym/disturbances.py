"""External force schedules applied through `xfrc_applied`, and periodic velocity pushes.

A schedule draws a horizontal force (uniform magnitude, uniform direction) at the start of each period
and holds it for `duration_steps` control steps; in between, no force acts. `duration == period` is a
continuous disturbance, a short duration an impulse. The same force vector acts on each body of the target
group ("centroid": the root body; "hands" and "feet": each of the two bodies), at the body's centre of mass.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from zerith_gym import robot
from zerith_gym.arrays import namespace

FORCE_TARGETS = {
    "centroid": (robot.ROOT_BODY,),
    "hands": robot.HAND_BODIES,
    "feet": robot.FOOT_BODIES,
}
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

    def __post_init__(self) -> None:
        if self.target not in FORCE_TARGETS:
            raise ValueError(
                f"ForceSchedule target must be one of {sorted(FORCE_TARGETS)}, got {self.target!r}"
            )
        if not 0 < self.duration_steps <= self.period_steps:
            raise ValueError("ForceSchedule needs 0 < duration_steps <= period_steps")

    @property
    def active(self) -> bool:
        return self.magnitude[1] > 0.0


NO_FORCE = ForceSchedule()


def horizontal_vectors(uniforms: np.ndarray, magnitude: tuple[float, float] | np.ndarray) -> np.ndarray:
    """Vectors (n, 3) of uniform magnitude in `magnitude` and uniform horizontal direction (numpy or JAX)."""
    xp = namespace(uniforms)
    norm = magnitude[0] + (magnitude[1] - magnitude[0]) * uniforms[:, 0]
    angle = 2.0 * np.pi * uniforms[:, 1]
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
