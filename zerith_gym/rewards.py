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
    swing = 1.0 - stance
    normal = foot_force[:, _NORMAL]
    terms = np.empty((n, len(REWARD_NAMES)))
    terms[:, 0] = 1.0  # alive
    terms[:, 1:3] = exps[:, 0:2]  # velocity tracking
    terms[:, 3] = (swing * exps[:, 2:4]).sum(axis=1)  # swing force
    terms[:, 4] = (stance * exps[:, 4:6]).sum(axis=1)  # stance velocity
    terms[:, 5] = sums[:, 9]  # raibert placement
    terms[:, 6] = (swing * sums[:, 10:12]).sum(axis=1)  # swing height
    terms[:, 7] = exps[:, 6]  # body height
    terms[:, 8] = sums[:, 20]  # z velocity
    terms[:, 9] = (foot_contact * sums[:, 4:6]).sum(axis=1)  # foot slip
    terms[:, 10] = exps[:, 7]  # hip position
    terms[:, 11] = np.exp(
        -10.0 * np.arccos(np.minimum(np.maximum(foot_up_z, -1.0), 1.0)).sum(axis=1)
    )  # feet orientation
    terms[:, 12] = (sums[:, 12:14] > 16.0 * normal * normal).any(axis=1)  # stumble: |F_xy| > 4 |F_z|
    terms[:, 13] = exps[:, 8]  # orientation
    terms[:, 14] = leg_collision
    terms[:, 15] = outside_limits
    terms[:, 16:22] = sums[:, 14:20]  # torques ... action smoothing, 2nd order
    terms[:, 19] = np.sqrt(terms[:, 19])  # action rate: |a_t|
    return terms


_TANGENTIAL = np.array([0, 1, 3, 4])
_NORMAL = np.array([2, 5])
