"""The Go2-like quadruped's task: legged_gym's observations, rewards and episode end (Rudin et al., 2022).

The HuRi paper trains its quadruped (appendix A.6) with legged_gym's Go2 settings; this module is that
task as a `LocomotionTask` on the step every robot shares (`zerith_gym.core.task`). Like the kernel, it is
written against the functions numpy and jax.numpy share.

Observations, in physical units (a running normalizer scales them, as for Zerith-1):
- policy (235): base linear velocity (trunk frame), base angular velocity, projected gravity (the world's
  -z in the trunk frame), command, joint positions minus the default pose, joint velocities, the last
  action, and the trunk's height above the ground at 187 points of a 1.6 m x 1.0 m grid around it (17 x 11,
  0.1 m apart, turned with the robot's heading; clipped to [-0.5, 1.5] m). legged_gym's rough-terrain
  observation with its noise (0.1 m/s, 0.2 rad/s, 0.05, 0.01 rad, 1.5 rad/s, 0.1 m).
- critic: the noiseless policy entries, then the trunk's height, foot contacts and forces, the external
  force and the domain parameters (scaled like Zerith-1's).

Rewards: legged_gym's terms with its Go2 scales (`DEFAULT_REWARD_WEIGHTS`), each times the control period;
as legged_gym's `only_positive_rewards`, a step's reward is the sum of the terms clipped at 0 (the
terms in `info["reward_terms"]` are before the clip). An episode ends when the trunk touches the ground.
"""

from __future__ import annotations

import numpy as np

from zerith_gym.core.arrays import namespace
from zerith_gym.core.observations import HEIGHT_SCALE, MAX_EXTERNAL_FORCE, layout_slices
from zerith_gym.core.randomization import DOMAIN_SIZES, DOMAIN_VECTOR_SIZE, WIDEST, domain_bounds
from zerith_gym.core.task import CONTACT_THRESHOLD, Judgement, LocomotionTask, TaskConstants, TaskState
from zerith_gym.go2like import constants as quad
from zerith_gym.terrain.ground import Terrain

TRACKING_SIGMA = 0.25
"""Width of the velocity-tracking kernels exp(-error^2 / sigma)."""
AIR_TIME_TARGET = 0.5
"""Seconds of swing the feet-air-time term pays for beyond (and charges for below) at each touchdown."""
MOVING_COMMAND = 0.1
"""Planar command (m/s) below which the feet-air-time term pays nothing (standing still)."""
SOFT_LIMIT = 0.9
"""Share of each joint's range (centred) beyond which the joint-limit penalty applies (legged_gym's Go2)."""

DEFAULT_REWARD_WEIGHTS: dict[str, float] = {
    "tracking_lin_vel": 1.0,
    "tracking_ang_vel": 0.5,
    "feet_air_time": 1.0,
    "lin_vel_z": -2.0,
    "ang_vel_xy": -0.05,
    "torques": -2e-4,
    "dof_acc": -2.5e-7,
    "collision": -1.0,
    "action_rate": -0.01,
    "dof_pos_limits": -10.0,
}
"""legged_gym's reward terms and scales for the Go2, in the order of the reward columns."""

HEIGHT_POINTS = np.array([(x, y) for x in np.linspace(-0.8, 0.8, 17) for y in np.linspace(-0.5, 0.5, 11)])
"""(187, 2) points (m, in the trunk's heading frame) where the trunk's height above the ground is measured."""
HEIGHT_CLIP = (-0.5, 1.5)

POLICY_LAYOUT: tuple[tuple[str, int], ...] = (
    ("base_linear_velocity", 3),
    ("base_angular_velocity", 3),
    ("projected_gravity", 3),
    ("command", 3),
    ("joint_position_offset", quad.NUM_JOINTS),
    ("joint_velocity", quad.NUM_JOINTS),
    ("last_action", quad.NUM_JOINTS),
    ("height_samples", len(HEIGHT_POINTS)),
)
CRITIC_LAYOUT: tuple[tuple[str, int], ...] = (
    *POLICY_LAYOUT,  # noiseless
    ("base_height", 1),
    ("foot_contact", len(quad.LEGS)),
    ("foot_contact_force", 3 * len(quad.LEGS)),
    ("external_force", 3),
    *((f"domain_{name}", size) for name, size in DOMAIN_SIZES.items()),
)
POLICY_SIZE = sum(size for _, size in POLICY_LAYOUT)
CRITIC_SIZE = sum(size for _, size in CRITIC_LAYOUT)
POLICY_NOISE = {
    "base_linear_velocity": 0.1,
    "base_angular_velocity": 0.2,
    "projected_gravity": 0.05,
    "joint_position_offset": 0.01,
    "joint_velocity": 1.5,
    "height_samples": 0.1,
}
"""legged_gym's noise scales: half width of each policy block's uniform training noise (its units)."""


def _noise_scale() -> np.ndarray:
    scale, slices = np.zeros(POLICY_SIZE), layout_slices(POLICY_LAYOUT)
    for name, value in POLICY_NOISE.items():
        scale[slices[name]] = value
    return scale


def _critic_affine() -> tuple[np.ndarray, np.ndarray]:
    """Known scales of the critic's entries, as Zerith-1's (`zerith_gym.zerith1.observations`):
    (value - offset) * scale brings each to about [-1, 1]."""
    offset, scale = np.zeros(CRITIC_SIZE), np.ones(CRITIC_SIZE)
    critic = layout_slices(CRITIC_LAYOUT)
    scale[critic["base_angular_velocity"]] = 0.25
    scale[critic["joint_velocity"]] = 0.05
    offset[critic["base_height"]] = quad.STANDING_HEIGHT
    scale[critic["base_height"]] = HEIGHT_SCALE
    scale[critic["foot_contact_force"]] = 1.0 / (quad.TOTAL_MASS * 9.81)
    scale[critic["external_force"]] = 1.0 / MAX_EXTERNAL_FORCE
    low, high = domain_bounds(WIDEST)
    domain = slice(CRITIC_SIZE - DOMAIN_VECTOR_SIZE, CRITIC_SIZE)
    offset[domain], scale[domain] = (low + high) / 2.0, 2.0 / (high - low)
    return offset.astype(np.float32), scale.astype(np.float32)


CRITIC_OFFSET, CRITIC_SCALE = _critic_affine()


def _heights_around(r: quad.Sensors, terrain: Terrain) -> tuple[np.ndarray, np.ndarray]:
    """The trunk's height above the ground under it (n,), and at `HEIGHT_POINTS` around it (n, 187)."""
    xp = namespace(r.base_pos)
    base = r.base_pos
    if terrain.is_plane:
        height = base[:, 2]
        return height, xp.broadcast_to(height[:, None], (height.shape[0], len(HEIGHT_POINTS)))
    heading = r.base_heading
    norm = xp.hypot(heading[:, 0:1], heading[:, 1:2]) + 1e-9
    cos_yaw, sin_yaw = heading[:, 0:1] / norm, heading[:, 1:2] / norm
    x, y = HEIGHT_POINTS[:, 0], HEIGHT_POINTS[:, 1]
    points = base[:, None, :2] + xp.stack([cos_yaw * x - sin_yaw * y, sin_yaw * x + cos_yaw * y], axis=-1)
    return base[:, 2] - terrain.height_at(base[:, :2]), base[:, 2:3] - terrain.height_at(points)


def observations(
    state: TaskState, r: quad.Sensors, noise: np.ndarray | None, c: TaskConstants
) -> tuple[np.ndarray, np.ndarray]:
    """Policy and critic observations (float32) of n robots after their last action `state.actions[:, 0]`."""
    xp = namespace(r.base_pos)
    base_height, heights = _heights_around(r, c.terrain)
    policy = xp.concatenate(
        [
            r.base_linvel,
            r.base_angvel,
            -r.base_up,
            state.command,
            r.joint_pos - quad.DEFAULT_JOINT_POS,
            r.joint_vel,
            state.actions[:, 0],
            xp.clip(heights, *HEIGHT_CLIP),
        ],
        axis=1,
    )
    critic = xp.concatenate(
        [
            policy,
            base_height[:, None],
            r.foot_force[:, 2::3] > CONTACT_THRESHOLD,
            r.foot_force,
            state.force,
            state.domain_vector,
        ],
        axis=1,
        dtype=np.float32,
    )
    critic = (critic - CRITIC_OFFSET) * CRITIC_SCALE
    if noise is not None:
        policy = policy + noise
    return policy.astype(np.float32), critic


def reward_terms(
    state: TaskState, r: quad.Sensors, first_contact: np.ndarray, air_time: np.ndarray, c: TaskConstants
) -> np.ndarray:
    """The unweighted terms (n, K) in `DEFAULT_REWARD_WEIGHTS` order; `air_time` (n, 4) is each foot's
    swing time up to this step and `first_contact` which feet touch down now."""
    xp = namespace(r.base_pos)
    command, linvel, angvel = state.command, r.base_linvel, r.base_angvel
    lin_error = xp.sum((command[:, :2] - linvel[:, :2]) ** 2, axis=1)
    moving = xp.hypot(command[:, 0], command[:, 1]) > MOVING_COMMAND
    low, high = c.soft_limits
    q = r.joint_pos
    beyond = xp.maximum(low - q, 0.0) + xp.maximum(q - high, 0.0)
    joint_acc = (r.joint_vel - state.joint_vel) / quad.CONTROL_DT
    return xp.stack(
        [
            xp.exp(-lin_error / TRACKING_SIGMA),
            xp.exp(-((command[:, 2] - angvel[:, 2]) ** 2) / TRACKING_SIGMA),
            xp.sum((air_time - AIR_TIME_TARGET) * first_contact, axis=1) * moving,
            linvel[:, 2] ** 2,
            xp.sum(angvel[:, :2] ** 2, axis=1),
            xp.sum(r.joint_torque**2, axis=1),
            xp.sum(joint_acc**2, axis=1),
            xp.sum(r.leg_contact > 0, axis=1).astype(r.base_pos.dtype),
            xp.sum((state.actions[:, 0] - state.actions[:, 1]) ** 2, axis=1),
            xp.sum(beyond, axis=1),
        ],
        axis=1,
    )


def judge(
    state: TaskState, r: quad.Sensors, gait_step: np.ndarray, noise: np.ndarray | None, c: TaskConstants
) -> tuple[Judgement, TaskState]:
    """A control step of n quadrupeds judged from their sensors, and their feet's air time moved on."""
    xp = namespace(r.base_pos)
    contact = r.foot_force[:, 2::3] > CONTACT_THRESHOLD
    touching = contact | state.last_contact  # legged_gym's filter: MuJoCo's contacts can flicker too
    air_time = state.feet_air_time + quad.CONTROL_DT
    first_contact = (state.feet_air_time > 0.0) & touching
    terms = reward_terms(state, r, first_contact, air_time, c) * c.reward_weights
    policy, critic = observations(state, r, noise, c)
    velocity_error = r.base_linvel[:, :2] - state.command[:, :2]
    judged = Judgement(
        policy_obs=policy,
        critic_obs=critic,
        terms=terms,
        reward=xp.maximum(terms.sum(axis=1), 0.0),
        fall=r.base_contact[:, 0] > 0,
        lin_vel_error=xp.hypot(velocity_error[:, 0], velocity_error[:, 1]),
        ang_vel_error=xp.abs(r.base_angvel[:, 2] - state.command[:, 2]),
    )
    return judged, state._replace(feet_air_time=air_time * ~touching, last_contact=contact)


DEPLOYMENT_NOTES = {
    "base_linear_velocity": "trunk velocity in the trunk frame (m/s): an estimate on the robot (legged_gym's "
    "policy reads it too)",
    "base_angular_velocity": "gyro at the trunk, trunk frame (rad/s)",
    "projected_gravity": "the gravity direction in the trunk (IMU) frame, normalized",
    "command": "commanded vx, vy (m/s) and yaw rate (rad/s), in the base's heading frame",
    "joint_position_offset": "joint positions minus default_joint_pos, in joint_names order (rad)",
    "joint_velocity": "joint velocities, in joint_names order (rad/s)",
    "last_action": "the action this graph returned at the previous control step (zeros at the start)",
    "height_samples": "the trunk's height above the ground at height_points (m; x forward, y left in the "
    "trunk's heading frame), clipped to height_clip: needs a height map around the robot",
}
"""How each block of the quadruped's policy observation is measured on the robot."""

QUADRUPED_TASK = LocomotionTask(
    robot=quad.GO2LIKE,
    policy_size=POLICY_SIZE,
    critic_size=CRITIC_SIZE,
    noise_scale=_noise_scale(),
    reward_weights=DEFAULT_REWARD_WEIGHTS,
    judge=judge,
    observe=observations,
    soft_limit=SOFT_LIMIT,
    default_scenario="quadruped-train",
    critic_layout=CRITIC_LAYOUT,
    critic_offset=CRITIC_OFFSET,
    critic_scale=CRITIC_SCALE,
    policy_layout=POLICY_LAYOUT,
    deployment_notes=DEPLOYMENT_NOTES,
    deployment_extras={"height_points": HEIGHT_POINTS.tolist(), "height_clip": list(HEIGHT_CLIP)},
)
"""The Go2-like quadruped on legged_gym's task."""
