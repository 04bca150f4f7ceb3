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


def _sq(x: np.ndarray) -> np.ndarray:
    """Sum of squares over the last axis."""
    return np.einsum("...i,...i->...", x, x)


def reward_terms(
    *,
    command: np.ndarray,  # (n, 3): vx, vy, yaw rate
    base_linvel: np.ndarray,  # (n, 3) body frame
    base_angvel: np.ndarray,  # (n, 3) body frame
    base_up: np.ndarray,  # (n, 3) world z axis in the body frame
    base_height: np.ndarray,  # (n,) above the ground
    target_height: float,
    joint_vel: np.ndarray,  # (n, 12)
    joint_acc: np.ndarray,  # (n, 12)
    torques: np.ndarray,  # (n, 12)
    outside_limits: np.ndarray,  # (n,) bool
    hip_roll_yaw: np.ndarray,  # (n, 4) hip roll and yaw offsets
    foot_tilt: np.ndarray,  # (n, 2) angle (rad) of each sole from horizontal
    foot_vel_xy: np.ndarray,  # (n, 2, 2)
    foot_force: np.ndarray,  # (n, 2, 3) ground reaction on each foot
    foot_contact: np.ndarray,  # (n, 2) bool
    foot_clearance: np.ndarray,  # (n, 2) sole height above the ground
    foot_xy_yaw_frame: np.ndarray,  # (n, 2, 2) foot positions relative to the base, yaw frame
    stance: np.ndarray,  # (n, 2) C_foot, 1 = stance
    swing_target: np.ndarray,  # (n, 2)
    raibert_target: np.ndarray,  # (n, 2, 2)
    leg_collision: np.ndarray,  # (n,) bool
    action: np.ndarray,  # (n, 12) a_t
    last_action: np.ndarray,  # a_{t-1}
    last_last_action: np.ndarray,  # a_{t-2}
) -> np.ndarray:
    """All reward terms, unweighted, as an (n, len(REWARD_NAMES)) array."""
    n = command.shape[0]
    swing = 1.0 - stance
    force_sq = _sq(foot_force)
    foot_speed_sq = _sq(foot_vel_xy)
    tangential = np.sqrt(_sq(foot_force[..., :2]))
    action_step = action - last_action
    # The exponential terms, computed in one call: columns follow the order of use below.
    exps = np.exp(
        np.column_stack(
            [
                -5.0 * _sq(base_linvel[:, :2] - command[:, :2]),
                -5.0 * (base_angvel[:, 2] - command[:, 2]) ** 2,
                -force_sq / 100.0,
                -foot_speed_sq / 5.0,
                -1000.0 * (base_height - target_height) ** 2,
                -100.0 * _sq(hip_roll_yaw),
                -10.0 * foot_tilt.sum(axis=1),
                -10.0 * _sq(base_up[:, :2]),
            ]
        )
    )
    terms = np.empty((n, len(REWARD_NAMES)))
    terms[:, 0] = 1.0
    terms[:, 1] = exps[:, 0]
    terms[:, 2] = exps[:, 1]
    terms[:, 3] = (swing * exps[:, 2:4]).sum(axis=1)
    terms[:, 4] = (stance * exps[:, 4:6]).sum(axis=1)
    terms[:, 5] = _sq((foot_xy_yaw_frame - raibert_target).reshape(n, 4))
    terms[:, 6] = (swing * (foot_clearance - swing_target) ** 2).sum(axis=1)
    terms[:, 7] = exps[:, 6]
    terms[:, 8] = np.einsum("ij,ij->i", base_up, base_linvel) ** 2  # world-frame vertical speed squared
    terms[:, 9] = (foot_contact * foot_speed_sq).sum(axis=1)
    terms[:, 10] = exps[:, 7]
    terms[:, 11] = exps[:, 8]
    terms[:, 12] = (tangential > 4.0 * np.abs(foot_force[..., 2])).any(axis=1)
    terms[:, 13] = exps[:, 9]
    terms[:, 14] = leg_collision
    terms[:, 15] = outside_limits
    terms[:, 16] = _sq(torques)
    terms[:, 17] = _sq(joint_vel)
    terms[:, 18] = _sq(joint_acc)
    terms[:, 19] = np.sqrt(_sq(action))
    terms[:, 20] = _sq(action_step)
    terms[:, 21] = _sq(action_step - (last_action - last_last_action))
    return terms
