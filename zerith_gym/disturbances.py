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


def horizontal_vectors(uniforms: np.ndarray, magnitude: tuple[float, float]) -> np.ndarray:
    """Vectors (n, 3) with uniform magnitude in `magnitude` and uniform horizontal direction."""
    norm = magnitude[0] + (magnitude[1] - magnitude[0]) * uniforms[:, 0]
    angle = 2.0 * np.pi * uniforms[:, 1]
    return np.stack([norm * np.cos(angle), norm * np.sin(angle), np.zeros_like(norm)], axis=1)


def update_forces(
    step: np.ndarray, uniforms: np.ndarray, force: np.ndarray, schedule: ForceSchedule
) -> np.ndarray:
    """The force (n, 3) acting during control step `step` (n,), given the previous one; draws at period starts."""
    if not schedule.active:
        return force
    since_start = step - schedule.start_step
    in_period = since_start % schedule.period_steps
    draw = (since_start >= 0) & (in_period == 0)
    on = (since_start >= 0) & (in_period < schedule.duration_steps)
    force = np.where(draw[:, None], horizontal_vectors(uniforms, schedule.magnitude), force)
    return force * on[:, None]


def push_kicks(
    step: np.ndarray, uniforms: np.ndarray, magnitude: tuple[float, float], interval_steps: int
) -> np.ndarray | None:
    """Horizontal base velocity kicks (n, 2) due at control step `step`, or None when none is due."""
    due = (step > 0) & (step % interval_steps == 0)
    if magnitude[1] <= 0.0 or not due.any():
        return None
    return horizontal_vectors(uniforms, magnitude)[:, :2] * due[:, None]
