"""Reward terms of the paper's Table 4: their weights, one named function per term, and the fused batch path.

The step reward is control_dt * sum_k weight_k * term_k (rewards scaled by the control period, as in
legged_gym, so an episode's return does not depend on the control rate). Every term reads a `RewardInputs`
of n robots and returns (n,) values.

Two implementations compute the same (n, K) array of unweighted terms, columns in `REWARD_NAMES` order:

- `TERMS` / `reward_terms_by_name`: one small function per term, written as the paper's table reads. This
  is the specification: read it to see what a term pays for, change it to try a new term. It is written
  against the functions numpy and jax.numpy share, and the MJX backend runs it under `jax.jit`.
- `reward_terms`: the same numbers in about twenty numpy calls for the whole batch (every squared norm the
  terms need in one row per robot, summed per group in one pass), which the CPU env calls every step. It
  reads its constants from the same named tables, and the tests hold it to `reward_terms_by_name`.
  `reward_terms_for` picks the one for the arrays at hand.
"""

from __future__ import annotations

from collections.abc import Callable
from types import ModuleType
from typing import NamedTuple

import numpy as np

from zerith_gym.core.arrays import namespace

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

KERNEL_SHARPNESS: dict[str, float] = {
    "lin_vel_tracking": 5.0,
    "yaw_vel_tracking": 5.0,
    "swing_force": 1.0 / 100.0,
    "stance_velocity": 1.0 / 5.0,
    "body_height": 1000.0,
    "hip_position": 100.0,
    "orientation": 10.0,
    "feet_orientation": 10.0,
}
"""c of each kernel term exp(-c x), x being a squared norm (the feet tilt: a sum of angles)."""
STUMBLE_FORCE_RATIO = 4.0
"""A foot stumbles when its horizontal contact force exceeds this multiple of the vertical one."""


class RewardInputs(NamedTuple):
    """What the reward terms read, for n robots (leading axis n)."""

    command: np.ndarray  # (n, 3): vx, vy, yaw rate
    base_linvel: np.ndarray  # (n, 3) body frame
    base_angvel: np.ndarray  # (n, 3) body frame
    base_up: np.ndarray  # (n, 3) world z axis in the body frame
    height_error: np.ndarray  # (n,) pelvis height above ground minus its target
    joint_vel: np.ndarray  # (n, 12)
    joint_acc: np.ndarray  # (n, 12)
    torques: np.ndarray  # (n, 12)
    outside_limits: np.ndarray  # (n,) bool: a joint beyond its soft limits
    hip_roll_yaw: np.ndarray  # (n, 4) hip roll and yaw offsets from the default pose
    foot_up_z: np.ndarray  # (n, 2) cosine of each sole's tilt from horizontal
    foot_speed_xy: np.ndarray  # (n, 4) horizontal foot velocities: left x, y, right x, y
    foot_force: np.ndarray  # (n, 6) ground reaction on each foot: left xyz, right xyz
    foot_contact: np.ndarray  # (n, 2) bool
    swing_height_error: np.ndarray  # (n, 2) sole clearance minus its target
    raibert_error: np.ndarray  # (n, 4) foot xy minus the Raibert target (base yaw frame): x l, x r, y l, y r
    stance: np.ndarray  # (n, 2) desired contact C_foot, 1 = stance
    leg_collision: np.ndarray  # (n,) bool
    action: np.ndarray  # (n, 12) a_t
    last_action: np.ndarray  # a_{t-1}
    last_last_action: np.ndarray  # a_{t-2}


# ------------------------------------------------------------------------------ the terms, one by one
# Written against the functions numpy and jax.numpy share (`zerith_gym.core.arrays`): the MJX backend runs
# these very functions under `jax.jit`, where XLA fuses them.
def _xp(x: RewardInputs) -> ModuleType:
    return namespace(x.command)


def _squared_norm(x: np.ndarray) -> np.ndarray:
    return (x * x).sum(axis=-1)


def _kernel(name: str, squared: np.ndarray, xp: ModuleType) -> np.ndarray:
    return xp.exp(-KERNEL_SHARPNESS[name] * squared)


def _per_foot(x: np.ndarray) -> np.ndarray:
    """(n, 2k) -> (n, 2, k): left foot's values, then right foot's."""
    return x.reshape(len(x), 2, -1)


def alive(x: RewardInputs) -> np.ndarray:
    """1 for every step the robot is up."""
    return _xp(x).ones(len(x.command))


def lin_vel_tracking(x: RewardInputs) -> np.ndarray:
    """exp(-5 |v_xy - v_cmd,xy|^2): follow the commanded planar velocity (body frame)."""
    return _kernel("lin_vel_tracking", _squared_norm(x.base_linvel[:, :2] - x.command[:, :2]), _xp(x))


def yaw_vel_tracking(x: RewardInputs) -> np.ndarray:
    """exp(-5 (w_z - w_cmd)^2): follow the commanded yaw rate."""
    return _kernel("yaw_vel_tracking", (x.base_angvel[:, 2] - x.command[:, 2]) ** 2, _xp(x))


def swing_force(x: RewardInputs) -> np.ndarray:
    """sum_feet (1 - C_foot) exp(-|F_foot|^2 / 100): no ground force on a foot that should swing."""
    kernel = _kernel("swing_force", _squared_norm(_per_foot(x.foot_force)), _xp(x))
    return ((1.0 - x.stance) * kernel).sum(axis=1)


def stance_velocity(x: RewardInputs) -> np.ndarray:
    """sum_feet C_foot exp(-|v_foot,xy|^2 / 5): a foot that should stand stays still."""
    kernel = _kernel("stance_velocity", _squared_norm(_per_foot(x.foot_speed_xy)), _xp(x))
    return (x.stance * kernel).sum(axis=1)


def raibert_placement(x: RewardInputs) -> np.ndarray:
    """|p_foot,xy - p_raibert|^2 over both feet: place the feet where the Raibert heuristic says."""
    return _squared_norm(x.raibert_error)


def swing_height(x: RewardInputs) -> np.ndarray:
    """sum_feet (1 - C_foot) (h_foot - h_target)^2: lift a swinging foot to the clock's target height."""
    return ((1.0 - x.stance) * x.swing_height_error**2).sum(axis=1)


def body_height(x: RewardInputs) -> np.ndarray:
    """exp(-1000 (h - h_target)^2): keep the pelvis at its standing height."""
    return _kernel("body_height", x.height_error**2, _xp(x))


def z_velocity(x: RewardInputs) -> np.ndarray:
    """v_z^2: no bouncing (world-frame vertical speed)."""
    return (x.base_up * x.base_linvel).sum(axis=1) ** 2


def foot_slip(x: RewardInputs) -> np.ndarray:
    """sum_feet contact |v_foot,xy|^2: a foot on the ground does not slide."""
    return (x.foot_contact * _squared_norm(_per_foot(x.foot_speed_xy))).sum(axis=1)


def hip_position(x: RewardInputs) -> np.ndarray:
    """exp(-100 |q_hip roll, yaw - default|^2): keep the hips' roll and yaw near the default pose."""
    return _kernel("hip_position", _squared_norm(x.hip_roll_yaw), _xp(x))


def feet_orientation(x: RewardInputs) -> np.ndarray:
    """exp(-10 sum_feet tilt): keep the soles flat."""
    xp = _xp(x)
    tilt = xp.arccos(xp.clip(x.foot_up_z, -1.0, 1.0))
    return _kernel("feet_orientation", tilt.sum(axis=1), xp)


def feet_stumble(x: RewardInputs) -> np.ndarray:
    """1 if a foot's horizontal contact force exceeds 4 times its vertical one (hitting an obstacle)."""
    xp = _xp(x)
    force = _per_foot(x.foot_force)
    horizontal = xp.hypot(force[..., 0], force[..., 1])
    return (horizontal > STUMBLE_FORCE_RATIO * xp.abs(force[..., 2])).any(axis=1).astype(x.torques.dtype)


def orientation(x: RewardInputs) -> np.ndarray:
    """exp(-10 |g_xy|^2) of the projected gravity: keep the pelvis upright."""
    return _kernel("orientation", _squared_norm(x.base_up[:, :2]), _xp(x))


def leg_collision(x: RewardInputs) -> np.ndarray:
    """1 if the thighs or shanks of the two legs touch."""
    return x.leg_collision.astype(x.torques.dtype)


def joint_limit(x: RewardInputs) -> np.ndarray:
    """1 if a joint is beyond its soft limits."""
    return x.outside_limits.astype(x.torques.dtype)


def torques(x: RewardInputs) -> np.ndarray:
    """|tau|^2."""
    return _squared_norm(x.torques)


def joint_velocities(x: RewardInputs) -> np.ndarray:
    """|dq|^2."""
    return _squared_norm(x.joint_vel)


def joint_accelerations(x: RewardInputs) -> np.ndarray:
    """|ddq|^2 (finite difference of joint velocities over a control step)."""
    return _squared_norm(x.joint_acc)


def action_rate(x: RewardInputs) -> np.ndarray:
    """|a_t|: the size of the action."""
    return _xp(x).sqrt(_squared_norm(x.action))


def action_smoothing(x: RewardInputs) -> np.ndarray:
    """|a_{t-1} - a_t|^2: first difference of the actions."""
    return _squared_norm(x.last_action - x.action)


def action_smoothing_2(x: RewardInputs) -> np.ndarray:
    """|a_{t-2} - 2 a_{t-1} + a_t|^2: second difference of the actions."""
    return _squared_norm(x.last_last_action - 2.0 * x.last_action + x.action)


TERMS: dict[str, Callable[[RewardInputs], np.ndarray]] = {name: globals()[name] for name in REWARD_NAMES}
"""Each reward term's function, by name, in `REWARD_NAMES` order."""


def reward_terms_by_name(x: RewardInputs) -> np.ndarray:
    """All reward terms, unweighted, (n, len(REWARD_NAMES)): one function call per term."""
    return _xp(x).stack([TERMS[name](x) for name in REWARD_NAMES], axis=1)


# ----------------------------------------------------------------------------------- the fused path
# Every squared quantity the terms need is written into one row per robot and summed per group in one
# `np.add.reduceat`. Groups, in order, with their widths:
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
_GROUP = {name: k for k, (name, _) in enumerate(_GROUPS)}
_STARTS = np.cumsum([0] + [width for _, width in _GROUPS[:-1]])
_KERNEL_OF_GROUP = {  # the first groups are the kernels' squared norms
    "lin_vel_error": "lin_vel_tracking",
    "yaw_rate_error": "yaw_vel_tracking",
    "left_foot_force": "swing_force",
    "right_foot_force": "swing_force",
    "left_foot_speed": "stance_velocity",
    "right_foot_speed": "stance_velocity",
    "height_error": "body_height",
    "hip_roll_yaw": "hip_position",
    "base_tilt": "orientation",
}
if tuple(_KERNEL_OF_GROUP) != tuple(name for name, _ in _GROUPS[: len(_KERNEL_OF_GROUP)]):
    raise RuntimeError("the kernel groups must come first, in order")
_NUM_KERNELS = len(_KERNEL_OF_GROUP)
_EXP_COEF = -np.array([KERNEL_SHARPNESS[term] for term in _KERNEL_OF_GROUP.values()])


def _groups(*names: str) -> np.ndarray:
    return np.array([_GROUP[name] for name in names])


_FOOT_FORCE = _groups("left_foot_force", "right_foot_force")
_FOOT_SPEED = _groups("left_foot_speed", "right_foot_speed")
_SWING_HEIGHT_ERROR = _groups("left_swing_height_error", "right_swing_height_error")
_TANGENTIAL_FORCE = _groups("left_tangential_force", "right_tangential_force")
_PER_FOOT_KERNELS = np.concatenate([_FOOT_FORCE, _FOOT_SPEED])  # columns of the kernels, by foot
_PER_FOOT_SUMS = np.concatenate([_SWING_HEIGHT_ERROR, _FOOT_SPEED])  # columns of the squared norms
_FOOT_PAIRS = np.array([0, 2, 4, 6])  # reduceat starts: swing force, stance velocity, swing height, slip
_TANGENTIAL = np.array([0, 1, 3, 4])  # of a foot_force row: left x, y, right x, y
_NORMAL = np.array([2, 5])


def reward_terms(x: RewardInputs) -> np.ndarray:
    """All reward terms, unweighted, (n, len(REWARD_NAMES)); the same values as `reward_terms_by_name`."""
    n = len(x.command)
    step = x.action - x.last_action
    errors = np.concatenate(
        [
            x.base_linvel[:, :2] - x.command[:, :2],
            x.base_angvel[:, 2:3] - x.command[:, 2:3],
            x.foot_force,
            x.foot_speed_xy,
            x.height_error[:, None],
            x.hip_roll_yaw,
            x.base_up[:, :2],
            x.raibert_error,
            x.swing_height_error,
            x.foot_force[:, _TANGENTIAL],
            x.torques,
            x.joint_vel,
            x.joint_acc,
            x.action,
            step,
            step - (x.last_action - x.last_last_action),
            np.einsum("ij,ij->i", x.base_up, x.base_linvel)[:, None],
        ],
        axis=1,
    )
    sums = np.add.reduceat(errors * errors, _STARTS, axis=1)  # (n, groups)
    kernels = np.exp(sums[:, :_NUM_KERNELS] * _EXP_COEF)
    swing = 1.0 - x.stance
    per_foot = np.add.reduceat(  # swing_force, stance_velocity, swing_height, foot_slip
        np.concatenate([swing, x.stance, swing, x.foot_contact], axis=1)
        * np.concatenate([kernels[:, _PER_FOOT_KERNELS], sums[:, _PER_FOOT_SUMS]], axis=1),
        _FOOT_PAIRS,
        axis=1,
    )
    tilt = np.arccos(np.minimum(np.maximum(x.foot_up_z, -1.0), 1.0))
    normal = x.foot_force[:, _NORMAL]
    stumble = np.logical_or.reduce(
        sums[:, _TANGENTIAL_FORCE] > STUMBLE_FORCE_RATIO**2 * normal * normal, axis=1
    )
    pool = np.concatenate(
        [
            kernels,
            sums,
            per_foot,
            np.exp(-KERNEL_SHARPNESS["feet_orientation"] * np.add.reduce(tilt, axis=1))[:, None],
            stumble[:, None],
            x.leg_collision[:, None],
            x.outside_limits[:, None],
            np.ones((n, 1)),
            np.sqrt(sums[:, _GROUP["action"], None]),
        ],
        axis=1,
    )
    return pool[:, _TERM_COLUMNS]


# Where each term is in the pool above: "kernel:" is a kernel of a group, "sum:" a group's squared norm.
_POOL = (
    *(f"kernel:{name}" for name in _KERNEL_OF_GROUP),
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
    "lin_vel_tracking": "kernel:lin_vel_error",
    "yaw_vel_tracking": "kernel:yaw_rate_error",
    "raibert_placement": "sum:raibert_error",
    "body_height": "kernel:height_error",
    "z_velocity": "sum:vertical_speed",
    "hip_position": "kernel:hip_roll_yaw",
    "orientation": "kernel:base_tilt",
    "torques": "sum:torques",
    "joint_velocities": "sum:joint_velocities",
    "joint_accelerations": "sum:joint_accelerations",
    "action_smoothing": "sum:action_step",
    "action_smoothing_2": "sum:action_step_2",
}
_TERM_COLUMNS = np.array([_POOL.index(_TERM_SOURCE.get(name, name)) for name in REWARD_NAMES])


def reward_terms_for(x: RewardInputs) -> np.ndarray:
    """All reward terms, unweighted: the fused numpy path for numpy inputs, the named functions for JAX
    (which `jax.jit` fuses by itself)."""
    return reward_terms(x) if _xp(x) is np else reward_terms_by_name(x)
