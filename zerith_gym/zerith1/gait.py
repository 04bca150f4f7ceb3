"""Gait clock: swing/stance schedule, Raibert foot placement and swing height targets.

The clock is a phase in [0, 1) that advances by control_dt / GAIT_PERIOD each step. The left foot runs
at the clock's phase and the right foot half a period later. Each foot is in stance for its phase in
[0, 0.5) and in swing for [0.5, 1) (a walking gait in which the feet take turns), as in Walk-These-Ways
(Margolis & Agrawal 2023), which the paper's feet-guidance rewards come from.

All functions take arrays with a leading batch axis.
"""

from __future__ import annotations

import numpy as np

GAIT_PERIOD = 0.7
"""Duration (s) of one full gait cycle (two steps)."""
SWING_HEIGHT = 0.09
"""Peak sole clearance (m) commanded mid-swing."""
CONTACT_SMOOTHING = 0.07
"""Standard deviation (phase units) of the smoothed edges of the stance indicator C_foot."""
_LOGISTIC_TO_NORMAL = 1.702
"""S(1.702 x) approximates the standard normal CDF within 0.01 (the kernel Walk-These-Ways uses)."""
FOOT_PHASE_OFFSETS = np.array([0.0, 0.5])
_EDGES = np.array([0.0, 0.5, 1.0, 1.5])


def foot_phases(phase: np.ndarray) -> np.ndarray:
    """Per-foot phase (n, 2) from the clock phase (n,)."""
    return (phase[:, None] + FOOT_PHASE_OFFSETS) % 1.0


def desired_contact(foot_phase: np.ndarray, smoothing: float = CONTACT_SMOOTHING) -> np.ndarray:
    """Smoothed stance indicator C_foot in [0, 1] (1 = the foot should be on the ground), shape (n, 2).

    C = S(phi) (1 - S(phi - 0.5)) + S(phi - 1) (1 - S(phi - 1.5)), with S(x) a smooth step of standard
    deviation `smoothing` (a logistic matched to the normal CDF); the second product makes the indicator
    continuous where the phase wraps from 1 to 0.
    """
    s = 1.0 / (1.0 + np.exp((_EDGES - foot_phase[..., None]) * (_LOGISTIC_TO_NORMAL / smoothing)))
    return s[..., 0] * (1.0 - s[..., 1]) + s[..., 2] * (1.0 - s[..., 3])


def swing_height_target(foot_phase: np.ndarray, height: float = SWING_HEIGHT) -> np.ndarray:
    """Commanded sole clearance (n, 2): a triangle over the swing half peaking at `height`, 0 in stance."""
    swing_progress = np.clip(2.0 * foot_phase - 1.0, 0.0, 1.0)
    return height * (1.0 - np.abs(1.0 - 2.0 * swing_progress))


def cycle_table(control_dt: float, period: float = GAIT_PERIOD) -> np.ndarray:
    """Every clock-driven signal at each control step of one gait cycle, (steps_per_cycle, 8).

    The clock advances by a whole number of control steps per cycle, so the signals repeat exactly and
    a per-step look-up replaces their computation. Columns: clock sin, cos; C_foot left, right; swing
    height target left, right; Raibert shift (seconds of commanded travel) left, right.
    """
    steps = round(period / control_dt)
    if abs(steps * control_dt - period) > 1e-9:
        raise ValueError(
            f"the gait period ({period} s) must be a whole number of control steps ({control_dt} s)"
        )
    phase = np.arange(steps) / steps
    feet = foot_phases(phase)
    return np.column_stack(
        [
            np.sin(2.0 * np.pi * phase),
            np.cos(2.0 * np.pi * phase),
            desired_contact(feet),
            swing_height_target(feet),
            (np.abs(1.0 - 2.0 * feet) - 0.5) * (0.5 * period),
        ]
    )
