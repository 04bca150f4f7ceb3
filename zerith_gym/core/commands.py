"""Velocity commands (vx, vy, yaw rate) in the base's heading frame."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from zerith_gym.core.arrays import namespace


@dataclass(frozen=True)
class CommandRanges:
    """Uniform ranges the commands are drawn from, and how often they are redrawn."""

    vx: tuple[float, float] = (0.0, 0.7)
    vy: tuple[float, float] = (-0.3, 0.3)
    yaw_rate: tuple[float, float] = (-0.5, 0.5)
    standing_probability: float = 0.1
    """Share of commands that are exactly zero (stand, stepping in place)."""
    resample_interval_s: float = 5.0


COMMAND_DRAWS = 4
"""Uniform numbers in [0, 1) consumed by one command draw."""


def command_bounds(ranges: CommandRanges) -> tuple[np.ndarray, np.ndarray]:
    """Lower and upper bounds (3,) each of (vx, vy, yaw rate)."""
    low = np.array([ranges.vx[0], ranges.vy[0], ranges.yaw_rate[0]])
    high = np.array([ranges.vx[1], ranges.vy[1], ranges.yaw_rate[1]])
    return low, high


def commands_from_uniforms(
    uniforms: np.ndarray, low: np.ndarray, high: np.ndarray, standing_probability: float | np.ndarray
) -> np.ndarray:
    """Commands (n, 3) from `uniforms` (n, 4) in [0, 1): standing flag, vx, vy, yaw rate (numpy or JAX)."""
    xp = namespace(uniforms)
    commands = low + (high - low) * uniforms[:, 1:4]
    return xp.where(uniforms[:, 0:1] < standing_probability, 0.0, commands)
