"""Reward terms of the paper's Table 4, as named columns of one array, and their weights.

The step reward is control_dt * sum_k weight_k * term_k (rewards scaled by the control period, as in
legged_gym, so an episode's return does not depend on the control rate). Each term is computed for a batch
of robots at once; `reward_terms` returns an (n, K) array whose columns follow `REWARD_NAMES`.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

DEFAULT_REWARD_WEIGHTS: dict[str, float] = {
    # task
    "alive": 0.5,
    "lin_vel_tracking": 1.5,
    "yaw_vel_tracking": 1.0,
    # feet guidance (gait clock)
    "swing_force": 5.0,
    "stance_velocity": 10.0,
    "raibert_placement": -30.0,
    "swing_height": -10.0,
    # regularization
    "body_height": 0.2,  # Table 4 prints -0.2 on a term that peaks at the target height: sign read as a typo
    "z_velocity": -0.02,
    "foot_slip": -0.04,
    "hip_position": 0.4,
    "feet_orientation": 0.4,
    "feet_stumble": -1.0,
    "orientation": 1.5,
    "leg_collision": -5.0,
    "joint_limit": -10.0,
    "torques": -1e-5,
    "joint_velocities": -1e-3,
    "joint_accelerations": -2.5e-7,
    "action_rate": -5e-5,
    "action_smoothing": -0.01,
    "action_smoothing_2": -0.01,
}
REWARD_NAMES: tuple[str, ...] = tuple(DEFAULT_REWARD_WEIGHTS)


def resolve_reward_weights(overrides: Mapping[str, float] | None = None) -> np.ndarray:
    """The weight vector (K,) in `REWARD_NAMES` order: the defaults with `overrides` applied."""
    weights = dict(DEFAULT_REWARD_WEIGHTS)
    for name, value in (overrides or {}).items():
        if name not in weights:
            raise ValueError(
                f"unknown reward term {name!r} in reward_weights; valid terms: {', '.join(REWARD_NAMES)}"
            )
        value = float(value)
        if not np.isfinite(value):
            raise ValueError(f"reward_weights[{name!r}] must be finite, got {value}")
        weights[name] = value
    return np.array([weights[name] for name in REWARD_NAMES])


# Every squared quantity the terms need is written into one row per robot and summed per group in one
# pass; the groups (start offsets below) come in this order.
_GROUPS = (
    ("lin_vel_error", 2),
    ("yaw_rate_error", 1),
    ("left_foot_force", 3),
    ("right_foot_force", 3),
    ("left_foot_speed", 2),
    ("right_foot_speed", 2),
    ("height_error", 1),
    ("hip_roll_yaw", 4),
    ("base_tilt", 2),
    ("raibert_error", 4),
    ("left_swing_height_error", 1),
    ("right_swing_height_error", 1),
    ("left_tangential_force", 2),
    ("right_tangential_force", 2),
    ("torques", 12),
    ("joint_velocities", 12),
    ("joint_accelerations", 12),
    ("action", 12),
    ("action_step", 12),
    ("action_step_2", 12),
    ("vertical_speed", 1),
)
_STARTS = np.cumsum([0] + [width for _, width in _GROUPS[:-1]])
# Exponential kernels: exp(coefficient * squared norm) over the first nine groups.
_EXP_COEF = np.array([-5.0, -5.0, -1.0 / 100.0, -1.0 / 100.0, -1.0 / 5.0, -1.0 / 5.0, -1000.0, -100.0, -10.0])


def reward_terms(
    *,
    command: np.ndarray,  # (n, 3): vx, vy, yaw rate
    base_linvel: np.ndarray,  # (n, 3) body frame
    base_angvel: np.ndarray,  # (n, 3) body frame
    base_up: np.ndarray,  # (n, 3) world z axis in the body frame
    height_error: np.ndarray,  # (n,) pelvis height above ground minus its target
    joint_vel: np.ndarray,  # (n, 12)
    joint_acc: np.ndarray,  # (n, 12)
    torques: np.ndarray,  # (n, 12)
    outside_limits: np.ndarray,  # (n,) bool: a joint beyond its soft limits
    hip_roll_yaw: np.ndarray,  # (n, 4) hip roll and yaw offsets from the default pose
    foot_up_z: np.ndarray,  # (n, 2) cosine of each sole's tilt from horizontal
    foot_speed_xy: np.ndarray,  # (n, 4) horizontal foot velocities: left x, y, right x, y
    foot_force: np.ndarray,  # (n, 6) ground reaction on each foot: left xyz, right xyz
    foot_contact: np.ndarray,  # (n, 2) bool
    swing_height_error: np.ndarray,  # (n, 2) sole clearance minus its target
    raibert_error: np.ndarray,  # (n, 4) foot xy minus the Raibert target (base yaw frame)
    stance: np.ndarray,  # (n, 2) C_foot, 1 = stance
    leg_collision: np.ndarray,  # (n,) bool
    action: np.ndarray,  # (n, 12) a_t
    last_action: np.ndarray,  # a_{t-1}
    last_last_action: np.ndarray,  # a_{t-2}
) -> np.ndarray:
    """All reward terms, unweighted, as an (n, len(REWARD_NAMES)) array (formulas in docs/zerith1.md)."""
    n = command.shape[0]
    step = action - last_action
    errors = np.concatenate(
        [
            base_linvel[:, :2] - command[:, :2],
            base_angvel[:, 2:3] - command[:, 2:3],
            foot_force,
            foot_speed_xy,
            height_error[:, None],
            hip_roll_yaw,
            base_up[:, :2],  # |g_xy| of the projected gravity
            raibert_error,
            swing_height_error,
            foot_force[:, _TANGENTIAL],
            torques,
            joint_vel,
            joint_acc,
            action,
            step,
            step - (last_action - last_last_action),
            np.einsum("ij,ij->i", base_up, base_linvel)[:, None],  # world-frame vertical speed
        ],
        axis=1,
    )
    sums = np.add.reduceat(errors * errors, _STARTS, axis=1)
    exps = np.exp(sums[:, :9] * _EXP_COEF)
    # Per-foot values weighted by the gait schedule (swing = 1 - C_foot) or the contacts, summed over feet.
    swing = 1.0 - stance
    per_foot = np.add.reduceat(
        np.concatenate([swing, stance, swing, foot_contact], axis=1)
        * np.concatenate([exps[:, 2:6], sums[:, 10:12], sums[:, 4:6]], axis=1),
        _FOOT_PAIRS,
        axis=1,
    )
    tilt = np.arccos(np.minimum(np.maximum(foot_up_z, -1.0), 1.0))
    normal = foot_force[:, _NORMAL]
    stumble = np.logical_or.reduce(sums[:, 12:14] > 16.0 * normal * normal, axis=1)  # |F_xy| > 4 |F_z|
    pool = np.concatenate(
        [
            exps,
            sums,
            per_foot,
            np.exp(-10.0 * np.add.reduce(tilt, axis=1))[:, None],
            stumble[:, None],
            leg_collision[:, None],
            outside_limits[:, None],
            np.ones((n, 1)),
            np.sqrt(sums[:, _ACTION : _ACTION + 1]),
        ],
        axis=1,
    )
    return pool[:, _TERM_COLUMNS]


# Where each term is in the pool above: "exp:" is exp(coefficient * squared norm) of a group, "sum:" the
# squared norm itself.
_POOL = (
    *(f"exp:{name}" for name, _ in _GROUPS[:9]),
    *(f"sum:{name}" for name, _ in _GROUPS),
    "swing_force",
    "stance_velocity",
    "swing_height",
    "foot_slip",
    "feet_orientation",
    "feet_stumble",
    "leg_collision",
    "joint_limit",
    "alive",
    "action_rate",
)
_TERM_SOURCE = {
    "lin_vel_tracking": "exp:lin_vel_error",
    "yaw_vel_tracking": "exp:yaw_rate_error",
    "raibert_placement": "sum:raibert_error",
    "body_height": "exp:height_error",
    "z_velocity": "sum:vertical_speed",
    "hip_position": "exp:hip_roll_yaw",
    "orientation": "exp:base_tilt",
    "torques": "sum:torques",
    "joint_velocities": "sum:joint_velocities",
    "joint_accelerations": "sum:joint_accelerations",
    "action_smoothing": "sum:action_step",
    "action_smoothing_2": "sum:action_step_2",
}
_TERM_COLUMNS = np.array([_POOL.index(_TERM_SOURCE.get(name, name)) for name in REWARD_NAMES])
_ACTION = [name for name, _ in _GROUPS].index("action")
_FOOT_PAIRS = np.array([0, 2, 4, 6])
_TANGENTIAL = np.array([0, 1, 3, 4])
_NORMAL = np.array([2, 5])
