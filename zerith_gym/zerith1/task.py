"""Zerith-1's task (`HUMANOID_TASK`): the paper's observations, Table-4 rewards and falls, and gait clock.

The humanoid's side of the step every robot shares (`zerith_gym.core.task`): the ground under the pelvis
and the soles (`ground`), the policy and critic observations (`observations`), what the reward terms read
(`reward_inputs`, the terms themselves in `zerith_gym.zerith1.rewards`), the falls, and `judge_step`, which
joins them after each control step. Like the kernel, it is written against the functions numpy and jax.numpy
share: the CPU backend calls it through `HUMANOID_TASK`, the MJX backend under `jax.jit`.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from zerith_gym.core.arrays import namespace
from zerith_gym.core.task import CONTACT_THRESHOLD, Judgement, LocomotionTask, TaskConstants, TaskState
from zerith_gym.terrain.ground import Terrain
from zerith_gym.zerith1 import constants as robot
from zerith_gym.zerith1 import gait
from zerith_gym.zerith1.observations import (
    CRITIC_LAYOUT,
    CRITIC_OFFSET,
    CRITIC_SCALE,
    CRITIC_SIZE,
    HEIGHT_SAMPLE_OFFSETS,
    POLICY_LAYOUT,
    POLICY_SIZE,
    policy_noise_scale,
)
from zerith_gym.zerith1.rewards import DEFAULT_REWARD_WEIGHTS, RewardInputs, reward_terms_for
from zerith_gym.zerith1.symmetry import ACTION_MIRROR, POLICY_MIRROR

FALL_HEIGHT = 0.45
"""A fall: the pelvis is lower than this (m) above the ground under it ..."""
FALL_TILT = 0.8
"""... or the pelvis is tilted more than this (rad) from upright."""


_COS_FALL_TILT = float(np.cos(FALL_TILT))
GAIT_TABLE = gait.cycle_table(robot.CONTROL_DT)
"""Every clock-driven signal at each control step of a gait cycle (see `gait.cycle_table`)."""
_HALF_STANCE = np.array([0.5 * robot.HIP_WIDTH, -0.5 * robot.HIP_WIDTH])


class Ground(NamedTuple):
    """Heights above the ground under the robots (the terrain's height subtracted)."""

    base_height: np.ndarray  # (n,) pelvis
    foot_clearance: np.ndarray  # (n, 2) soles
    height_samples: np.ndarray  # (n, 18) soles above the ground at the sample points around each foot
    foot_contact: np.ndarray  # (n, 2) bool


def ground(r: robot.Sensors, terrain: Terrain) -> Ground:
    """Pelvis and soles above the ground under them, and which feet touch it."""
    xp = namespace(r.foot_pos)
    foot_z = r.foot_pos[:, _FOOT_Z]
    if terrain.is_plane:
        base_height = r.base_pos[:, 2]
        foot_clearance = foot_z
        height_samples = foot_z[:, _FOOT_OF_SAMPLE]  # the sole height at every sample point
    else:
        n = len(foot_z)
        base_height = r.base_pos[:, 2] - terrain.height_at(r.base_pos[:, :2])
        feet_xy = r.foot_pos[:, _FOOT_XY].reshape(n, 2, 2)
        foot_clearance = foot_z - terrain.height_at(feet_xy)
        cos_yaw, sin_yaw = _yaw(r.base_heading)
        x, y = HEIGHT_SAMPLE_OFFSETS[:, 0], HEIGHT_SAMPLE_OFFSETS[:, 1]
        offsets = xp.stack([cos_yaw * x - sin_yaw * y, sin_yaw * x + cos_yaw * y], axis=-1)  # (n, 9, 2)
        points = feet_xy[:, :, None, :] + offsets[:, None]  # (n, 2, 9, 2)
        height_samples = (foot_z[:, :, None] - terrain.height_at(points)).reshape(n, -1)
    foot_contact = r.foot_force[:, _FOOT_Z] > CONTACT_THRESHOLD
    return Ground(base_height, foot_clearance, height_samples, foot_contact)


def observations(
    r: robot.Sensors,
    ground: Ground,
    clock: np.ndarray,
    command: np.ndarray,
    last_action: np.ndarray,
    force: np.ndarray,
    domain_vector: np.ndarray,
    noise: np.ndarray | None,
) -> tuple[np.ndarray, np.ndarray]:
    """Policy and critic observations (float32) of n robots; `noise` (n, POLICY_SIZE) is added to the
    policy's (None: noiseless). The policy's are in physical units, the critic's scaled by known ranges."""
    xp = namespace(r.base_up)
    up = r.base_up
    policy = xp.concatenate(
        [
            xp.arctan2(up[:, 1:2], up[:, 2:3]),  # roll
            xp.arcsin(xp.minimum(xp.maximum(-up[:, 0:1], -1.0), 1.0)),  # pitch
            r.base_angvel,
            clock[:, 0:2],
            command,
            r.joint_pos - robot.DEFAULT_JOINT_POS,
            r.joint_vel,
            last_action,
        ],
        axis=1,
    )
    critic = xp.concatenate(
        [
            policy,
            r.base_linvel,
            ground.base_height[:, None],
            ground.height_samples,
            ground.foot_contact,
            r.foot_force,
            clock[:, 2:4],  # desired contacts
            force,
            domain_vector,
        ],
        axis=1,
        dtype=np.float32,
    )
    critic = (critic - CRITIC_OFFSET) * CRITIC_SCALE  # known scales (observations.CRITIC_SCALE)
    if noise is not None:
        policy = policy + noise
    return policy.astype(np.float32), critic


def reward_inputs(
    r: robot.Sensors,
    ground: Ground,
    clock: np.ndarray,
    command: np.ndarray,
    actions: np.ndarray,
    last_joint_vel: np.ndarray,
    soft_limits: tuple[np.ndarray, np.ndarray],
) -> RewardInputs:
    """What the reward terms of n robots read (`zerith1.rewards`); `actions` (n, 3, 12) newest first."""
    xp = namespace(r.foot_pos)
    foot_pos = r.foot_pos
    # Feet relative to the base, in the base's yaw frame, against the Raibert targets.
    cos_yaw, sin_yaw = _yaw(r.base_heading)
    rel_x = foot_pos[:, 0::3] - r.base_pos[:, 0:1]
    rel_y = foot_pos[:, 1::3] - r.base_pos[:, 1:2]
    shift = clock[:, 6:8]  # Raibert: feet ahead/behind the hips by shift * commanded velocity
    raibert_error = xp.concatenate(
        [
            cos_yaw * rel_x + sin_yaw * rel_y - shift * command[:, 0:1],
            cos_yaw * rel_y - sin_yaw * rel_x - shift * command[:, 1:2] - _HALF_STANCE,
        ],
        axis=1,
    )
    joint_pos, joint_vel = r.joint_pos, r.joint_vel
    soft_low, soft_high = soft_limits
    return RewardInputs(
        command=command,
        base_linvel=r.base_linvel,
        base_angvel=r.base_angvel,
        base_up=r.base_up,
        height_error=ground.base_height - robot.STANDING_HEIGHT,
        joint_vel=joint_vel,
        joint_acc=(joint_vel - last_joint_vel) * (1.0 / robot.CONTROL_DT),
        torques=r.joint_torque,
        outside_limits=((joint_pos < soft_low) | (joint_pos > soft_high)).any(axis=1),
        hip_roll_yaw=joint_pos[:, _HIP_ROLL_YAW] - robot.DEFAULT_JOINT_POS[_HIP_ROLL_YAW],
        foot_up_z=r.foot_up[:, _FOOT_Z],
        foot_speed_xy=r.foot_linvel[:, _FOOT_XY],
        foot_force=r.foot_force,
        foot_contact=ground.foot_contact,
        swing_height_error=ground.foot_clearance - clock[:, 4:6],
        raibert_error=raibert_error,
        stance=clock[:, 2:4],
        leg_collision=r.leg_collision[:, 0] > 0,
        action=actions[:, 0],
        last_action=actions[:, 1],
        last_last_action=actions[:, 2],
    )


def falls(r: robot.Sensors, ground: Ground) -> np.ndarray:
    """Which robots fell: pelvis too low above the ground or tilted too far."""
    return (ground.base_height < FALL_HEIGHT) | (r.base_up[:, 2] < _COS_FALL_TILT)


def judge_step(
    r: robot.Sensors,
    gait_step: np.ndarray,
    command: np.ndarray,
    actions: np.ndarray,
    last_joint_vel: np.ndarray,
    force: np.ndarray,
    domain_vector: np.ndarray,
    noise: np.ndarray | None,
    constants: TaskConstants,
) -> Judgement:
    """Observations, rewards and falls of n robots from their sensor readings after a control step."""
    xp = namespace(r.base_pos)
    clock = GAIT_TABLE[gait_step] if xp is np else xp.asarray(GAIT_TABLE, r.base_pos.dtype)[gait_step]
    g = ground(r, constants.terrain)
    inputs = reward_inputs(r, g, clock, command, actions, last_joint_vel, constants.soft_limits)
    terms = reward_terms_for(inputs) * constants.reward_weights
    policy, critic = observations(r, g, clock, command, actions[:, 0], force, domain_vector, noise)
    linvel, angvel = r.base_linvel, r.base_angvel
    velocity_error = linvel[:, :2] - command[:, :2]
    return Judgement(
        policy_obs=policy,
        critic_obs=critic,
        terms=terms,
        reward=terms.sum(axis=1),
        fall=falls(r, g),
        lin_vel_error=xp.hypot(velocity_error[:, 0], velocity_error[:, 1]),
        ang_vel_error=xp.abs(angvel[:, 2] - command[:, 2]),
    )


def _humanoid_judge(
    state: TaskState, r: robot.Sensors, gait_step: np.ndarray, noise: np.ndarray | None, c: TaskConstants
) -> tuple[Judgement, TaskState]:
    judged = judge_step(
        r,
        gait_step,
        state.command,
        state.actions,
        state.joint_vel,
        state.force,
        state.domain_vector,
        noise,
        c,
    )
    return judged, state


def _humanoid_observe(
    state: TaskState, r: robot.Sensors, noise: np.ndarray | None, c: TaskConstants
) -> tuple[np.ndarray, np.ndarray]:
    xp = namespace(r.base_pos)
    table = GAIT_TABLE if xp is np else xp.asarray(GAIT_TABLE, r.base_pos.dtype)
    clock = table[state.gait_step]
    g = ground(r, c.terrain)
    return observations(
        r, g, clock, state.command, state.actions[:, 0], state.force, state.domain_vector, noise
    )


DEPLOYMENT_NOTES = {
    "base_roll_pitch": "pelvis roll = atan2(u_y, u_z) and pitch = asin(-u_x) (rad), where u is the world's "
    "up axis expressed in the pelvis (IMU) frame, i.e. minus the normalized gravity the IMU measures",
    "base_angular_velocity": "gyro at the pelvis, pelvis frame (rad/s)",
    "clock_sin_cos": "sin and cos of 2 pi phase, phase = (k mod gait_steps) / gait_steps where k counts the "
    "control steps since the controller started (k = 0 for the first observation)",
    "command": "commanded vx, vy (m/s) and yaw rate (rad/s), in the base's heading frame",
    "joint_position_offset": "joint positions minus default_joint_pos, in joint_names order (rad)",
    "joint_velocity": "joint velocities, in joint_names order (rad/s)",
    "last_action": "the action this graph returned at the previous control step (zeros at the start)",
}
"""How each block of Zerith-1's policy observation is measured on the robot."""

HUMANOID_TASK = LocomotionTask(
    robot=robot.ZERITH1,
    policy_size=POLICY_SIZE,
    critic_size=CRITIC_SIZE,
    noise_scale=policy_noise_scale(),
    reward_weights=DEFAULT_REWARD_WEIGHTS,
    judge=_humanoid_judge,
    observe=_humanoid_observe,
    critic_layout=CRITIC_LAYOUT,
    critic_offset=CRITIC_OFFSET,
    critic_scale=CRITIC_SCALE,
    policy_layout=POLICY_LAYOUT,
    deployment_notes=DEPLOYMENT_NOTES,
    deployment_extras={
        "gait_period": gait.GAIT_PERIOD,
        "gait_steps": round(gait.GAIT_PERIOD / robot.CONTROL_DT),
        "gait_foot_phase_offsets": gait.FOOT_PHASE_OFFSETS.tolist(),
    },
    gait_steps=len(GAIT_TABLE),
    policy_mirror=POLICY_MIRROR,
    action_mirror=ACTION_MIRROR,
)
"""Zerith-1 walking with the paper's gait clock, observations and Table-4 rewards."""
HUMANOID_DRAWS = HUMANOID_TASK.draws
"""Zerith-1's draws."""
STEP_DRAWS = HUMANOID_DRAWS.step
"""Uniform numbers each Zerith-1 robot draws per control step, used or not, to keep streams aligned."""
RESET_DRAWS = HUMANOID_DRAWS.reset
"""Uniform numbers each Zerith-1 robot draws per reset, in the order of `Draws.reset_parts`."""


_FOOT_XY = np.array([0, 1, 3, 4])  # of a (left xyz, right xyz) row
_FOOT_Z = np.array([2, 5])
_FOOT_OF_SAMPLE = np.repeat([0, 1], len(HEIGHT_SAMPLE_OFFSETS))
_HIP_ROLL_YAW = np.array([0, 1, 6, 7])  # joints: left hip yaw, roll, right hip yaw, roll


def _yaw(heading: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Cosine and sine (n, 1) each of each robot's yaw, from its heading vector (n, 3)."""
    xp = namespace(heading)
    norm = xp.hypot(heading[:, 0:1], heading[:, 1:2]) + 1e-9
    return heading[:, 0:1] / norm, heading[:, 1:2] / norm
