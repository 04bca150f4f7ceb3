"""The Zerith1-v0 task: what is observed, rewarded, randomized and disturbed, for a batch of robots.

The task's math is a set of pure functions over arrays with a leading robot axis, written against the
functions numpy and jax.numpy share (`zerith_gym.arrays`): `reset_values`, `step_disturbances`,
`action_targets`, `ground`, `observations`, `reward_inputs`, `judge_step`, `step_output`, and the two halves
of a control step over one `TaskState` record, `begin_step` and `end_step`. Both backends call them: the
CPU backend with numpy (`ZerithTask` below), the MJX backend with jax.numpy under `jax.jit`
(`zerith_gym.mjx`). What a scenario sets is handed to them as arrays (`ScenarioArrays`), so a curriculum
changes it without rebuilding anything.

`ZerithTask` holds the CPU task state of n robots (gait clock, commands, action history, external
forces, sampled domain parameters) and turns physics readings into observations, rewards and episode
ends. It never touches MuJoCo: the caller steps the physics. Per control step:

1. `before_physics(actions)` -> joint targets per delay lag, the external force, optional velocity kicks;
2. the caller runs `decimation` physics steps (sub-step j of robot i applies `targets[i, lags[i, j]]`);
3. `after_physics(sensordata, unstable)` -> observations, rewards, terminations, truncations, infos.

Each robot consumes a fixed amount of randomness per reset and per step from its own generator, so n
robots stepped together follow exactly the trajectories of n single environments seeded alike.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from functools import cached_property
from typing import Any, NamedTuple

import numpy as np

from zerith_gym import gait, robot
from zerith_gym.arrays import namespace
from zerith_gym.commands import COMMAND_DRAWS, command_bounds, commands_from_uniforms
from zerith_gym.disturbances import FORCE_DRAWS, PUSH_DRAWS, horizontal_vectors, push_due
from zerith_gym.observations import (
    CRITIC_LAYOUT,
    CRITIC_OFFSET,
    CRITIC_SCALE,
    CRITIC_SIZE,
    HEIGHT_SAMPLE_OFFSETS,
    POLICY_SIZE,
    layout_slices,
    policy_noise_scale,
)
from zerith_gym.randomization import (
    DOMAIN_DRAWS,
    DOMAIN_VECTOR_SIZE,
    DomainParams,
    delay_lags,
    domain_bounds,
    uniform_in,
)
from zerith_gym.rewards import DEFAULT_REWARD_WEIGHTS, RewardInputs, reward_terms_for
from zerith_gym.robot_spec import RobotSpec
from zerith_gym.scenarios import Scenario
from zerith_gym.terrain import Terrain
from zerith_gym.terrain_levels import LevelRule, TerrainLevels

EPISODE_STEPS = 1000
"""Default control steps in an episode (20 s): reaching them is a truncation."""
FALL_HEIGHT = 0.45
"""A fall: the pelvis is lower than this (m) above the ground under it ..."""
FALL_TILT = 0.8
"""... or the pelvis is tilted more than this (rad) from upright."""
CONTACT_THRESHOLD = 1.0
"""Normal force (N) above which a foot counts as in contact."""
JOINT_SOFT_LIMIT = 0.95
"""Share of each joint's range (centred) beyond which the joint-limit penalty applies."""


class Draws(NamedTuple):
    """Where each use of a robot's uniform numbers lies in its draws of a step and of a reset.

    Each robot draws `step` uniforms per control step (policy noise, force, command, push) and `reset` per
    reset, used or not, to keep its random stream aligned; the sizes follow its task's policy observation
    and joint count (`draw_layout`).
    """

    noise: slice
    force: slice
    command: slice
    push: slice
    step: int
    """Uniforms per control step."""
    reset_parts: Mapping[str, slice]
    """A reset's parts: domain, joint_scale, roll_pitch, spawn, command, step (the first observation's)."""
    reset: int
    """Uniforms per reset."""


def draw_layout(policy_size: int, num_joints: int) -> Draws:
    """The draws of a task whose policy observation has `policy_size` values, for `num_joints` joints."""
    noise = slice(0, policy_size)
    force = slice(noise.stop, noise.stop + FORCE_DRAWS)
    command = slice(force.stop, force.stop + COMMAND_DRAWS)
    push = slice(command.stop, command.stop + PUSH_DRAWS)
    reset = layout_slices(
        (
            ("domain", DOMAIN_DRAWS),
            ("joint_scale", num_joints),
            ("roll_pitch", 2),
            ("spawn", 2),
            ("command", COMMAND_DRAWS),
            ("step", push.stop),
        )
    )
    return Draws(noise, force, command, push, push.stop, reset, reset["step"].stop)


HUMANOID_DRAWS = draw_layout(POLICY_SIZE, robot.NUM_JOINTS)
"""Zerith-1's draws."""
STEP_DRAWS = HUMANOID_DRAWS.step
"""Uniform numbers each Zerith-1 robot draws per control step, used or not, to keep streams aligned."""
RESET_DRAWS = HUMANOID_DRAWS.reset
"""Uniform numbers each Zerith-1 robot draws per reset, in the order of `Draws.reset_parts`."""
_COS_FALL_TILT = float(np.cos(FALL_TILT))
GAIT_TABLE = gait.cycle_table(robot.CONTROL_DT)
"""Every clock-driven signal at each control step of a gait cycle (see `gait.cycle_table`)."""
_HALF_STANCE = np.array([0.5 * robot.HIP_WIDTH, -0.5 * robot.HIP_WIDTH])


class ScenarioArrays(NamedTuple):
    """What a scenario sets for the task, as arrays (`scenario_arrays`).

    The task functions read these instead of the `Scenario` itself, so that an env can follow another
    scenario between rollouts by swapping arrays (and a jitted MJX step needs no new trace).
    """

    due: np.ndarray  # (episode_steps, 2) bool, at each control step of an episode: command draw, push
    domain_low: np.ndarray  # (DOMAIN_VECTOR_SIZE,)
    domain_high: np.ndarray  # (DOMAIN_VECTOR_SIZE,)
    # The force program's table, read at a robot's episode step plus its episode's start offset:
    force_due: np.ndarray  # (2 episode_steps, 2) bool, at each table step: force draw, force on
    force_magnitude: np.ndarray  # (2 episode_steps, 2) N, the range of a force drawn at each table step
    force_target: np.ndarray  # (2 episode_steps,) int, the target (`disturbances.TARGET_INDEX`)
    force_direction: np.ndarray  # (2 episode_steps,) rad, a drawn force's direction (NaN: uniform)
    force_offsets: np.ndarray  # (k,) int, the table steps an episode may start at (one drawn per episode)
    push_velocity: np.ndarray  # (2,) m/s
    command_low: np.ndarray  # (3,)
    command_high: np.ndarray  # (3,)
    standing_probability: np.ndarray  # ()
    fixed_command: np.ndarray  # (3,) the command of every episode where `has_fixed_command`
    has_fixed_command: np.ndarray  # () bool
    noise_scale: np.ndarray  # (POLICY_SIZE,) half width of the policy observation noise
    init_roll_pitch: np.ndarray  # () half width (rad) of the reset roll and pitch
    init_joint_scale: np.ndarray  # (2,) range of the factor on the default joint positions at reset


def scenario_arrays(
    scenario: Scenario,
    command: tuple[float, float, float] | None,
    episode_steps: int,
    noise_scale: np.ndarray | None = None,
) -> ScenarioArrays:
    """The arrays of `scenario` (and of a fixed `command`, if any) for episodes of `episode_steps`, with
    `noise_scale` the training noise of each policy observation entry (None: Zerith-1's).

    The force table covers twice the episode, so that an episode may start anywhere in its first half
    (`ForceCycle.start_phases`); ValueError if the force program starts episodes later than that.
    """
    ranges = scenario.randomization
    command_interval = round(scenario.command_ranges.resample_interval_s / robot.CONTROL_DT)
    steps = np.arange(episode_steps)
    offsets = scenario.force.start_offsets
    if max(offsets) >= episode_steps:
        raise ValueError(
            f"scenario {scenario.name!r} starts episodes {max(offsets)} steps into its force cycle; "
            f"episodes of {episode_steps} steps allow fewer than {episode_steps}"
        )
    force = scenario.force.table(2 * episode_steps)
    due = np.column_stack(
        [
            (steps > 0) & (steps % command_interval == 0) & (command is None),
            push_due(episode_steps, round(ranges.push_interval_s / robot.CONTROL_DT), ranges.push_velocity),
        ]
    )
    low, high = command_bounds(scenario.command_ranges)
    domain_low, domain_high = domain_bounds(ranges)
    return ScenarioArrays(
        due=due,
        domain_low=domain_low,
        domain_high=domain_high,
        force_due=np.column_stack([force.draw, force.on]),
        force_magnitude=force.magnitude,
        force_target=force.target,
        force_direction=force.direction,
        force_offsets=np.array(offsets, dtype=int),
        push_velocity=np.array(ranges.push_velocity, dtype=float),
        command_low=low,
        command_high=high,
        standing_probability=np.array(scenario.command_ranges.standing_probability),
        fixed_command=np.zeros(3) if command is None else np.asarray(command, dtype=float),
        has_fixed_command=np.array(command is not None),
        noise_scale=(policy_noise_scale() if noise_scale is None else noise_scale) * ranges.observation_noise,
        init_roll_pitch=np.array(ranges.init_roll_pitch, dtype=float),
        init_joint_scale=np.array(ranges.init_joint_scale, dtype=float),
    )


class ResetValues(NamedTuple):
    """A new episode's start of n robots, drawn by `reset_values`."""

    qpos: np.ndarray  # (n, 7 + 12) base position (height 0: the caller puts the feet on the ground), joints
    domain_vector: np.ndarray  # (n, DOMAIN_VECTOR_SIZE), the critic's layout (`DomainParams.from_vector`)
    lags: np.ndarray  # (n, DECIMATION) control steps of delay of each physics sub-step's action
    command: np.ndarray  # (n, 3)
    noise_uniforms: np.ndarray  # (n, STEP_DRAWS) the uniforms of the first observation's noise
    force_offset: np.ndarray  # (n,) int, the step of the force table the episode starts at


def reset_values(
    uniforms: np.ndarray,
    sc: ScenarioArrays,
    spawn_xy: np.ndarray,
    spawn_jitter: float,
    robot: RobotSpec = robot.ZERITH1,
    draws: Draws = HUMANOID_DRAWS,
) -> ResetValues:
    """The start of new episodes of `robot` from uniforms (n, draws.reset) in [0, 1), in the order of
    `draws.reset_parts`, at spawn points `spawn_xy` (n, 2) moved by up to `spawn_jitter` m along x and y."""
    xp = namespace(uniforms)
    u = {name: uniforms[:, part] for name, part in draws.reset_parts.items()}
    half_roll_pitch = uniform_in((-1.0, 1.0), u["roll_pitch"]) * sc.init_roll_pitch / 2
    (cr, cp), (sr, sp) = xp.cos(half_roll_pitch).T, xp.sin(half_roll_pitch).T
    spawn = uniform_in((-1.0, 1.0), u["spawn"]) * spawn_jitter
    joint_scale = uniform_in(sc.init_joint_scale, u["joint_scale"])
    qpos = xp.concatenate(
        [
            spawn_xy + spawn,
            xp.stack([xp.zeros_like(cr), cp * cr, cp * sr, sp * cr, -sp * sr], axis=1),
            robot.default_joint_pos * joint_scale,
        ],
        axis=1,
    )
    domain_vector = uniform_in((sc.domain_low, sc.domain_high), u["domain"])
    domain = DomainParams.from_vector(domain_vector)
    drawn = commands_from_uniforms(u["command"], sc.command_low, sc.command_high, sc.standing_probability)
    # The start offset takes the first observation's force uniform, which nothing else reads (no force is
    # drawn at a reset): scenarios with one start offset draw exactly what they drew without any.
    choices = sc.force_offsets.shape[0]
    pick = xp.minimum((u["step"][:, draws.force.start] * choices).astype(int), choices - 1)
    return ResetValues(
        qpos=qpos,
        domain_vector=domain_vector,
        lags=delay_lags(domain.action_delay, robot.physics_dt, robot.decimation),
        command=xp.where(sc.has_fixed_command, sc.fixed_command, drawn),
        noise_uniforms=u["step"],
        force_offset=sc.force_offsets[pick],
    )


def action_targets(actions: np.ndarray, robot: RobotSpec = robot.ZERITH1) -> np.ndarray:
    """Joint targets (n, lags, 12) of an action history (n, lags, 12) in [-1, 1], newest first."""
    return robot.default_joint_pos + robot.action_scale * actions


class Disturbances(NamedTuple):
    """This control step's external force, command and base velocity kick of n robots."""

    force: np.ndarray  # (n, 3) on each body of the force target
    force_target: np.ndarray  # (n,) int, the bodies the force acts on (`disturbances.TARGET_INDEX`)
    command: np.ndarray  # (n, 3)
    kicks: np.ndarray  # (n, 2) horizontal velocity added to the base (zero unless a push is due)
    push: np.ndarray  # (n,) bool, a push is due


def step_disturbances(
    uniforms: np.ndarray,
    step_count: np.ndarray,
    force_offset: np.ndarray,
    force: np.ndarray,
    command: np.ndarray,
    sc: ScenarioArrays,
    draws: Draws = HUMANOID_DRAWS,
) -> Disturbances:
    """Redraw forces, commands and pushes where the scenario's tables say at each robot's episode step
    `step_count` (n,) (the force table at `step_count + force_offset`), from uniforms (n, draws.step)."""
    xp = namespace(uniforms, step_count)
    due = sc.due[step_count]
    at = step_count + force_offset
    force_due = sc.force_due[at]
    drawn_force = horizontal_vectors(uniforms[:, draws.force], sc.force_magnitude[at], sc.force_direction[at])
    drawn_command = commands_from_uniforms(
        uniforms[:, draws.command], sc.command_low, sc.command_high, sc.standing_probability
    )
    return Disturbances(
        force=xp.where(force_due[:, 0:1], drawn_force, force) * force_due[:, 1:2],
        force_target=sc.force_target[at],
        command=xp.where(due[:, 0:1], drawn_command, command),
        kicks=horizontal_vectors(uniforms[:, draws.push], sc.push_velocity)[:, :2] * due[:, 1:2],
        push=due[:, 1],
    )


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


def observation_noise(uniforms: np.ndarray, sc: ScenarioArrays, draws: Draws = HUMANOID_DRAWS) -> np.ndarray:
    """The policy observation noise (n, policy size) from a step's uniforms (n, draws.step)."""
    return (2.0 * uniforms[:, draws.noise] - 1.0) * sc.noise_scale


def reward_inputs(
    r: robot.Sensors,
    ground: Ground,
    clock: np.ndarray,
    command: np.ndarray,
    actions: np.ndarray,
    last_joint_vel: np.ndarray,
    soft_limits: tuple[np.ndarray, np.ndarray],
) -> RewardInputs:
    """What the reward terms of n robots read (zerith_gym.rewards); `actions` (n, 3, 12) newest first."""
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


class TaskConstants(NamedTuple):
    """What the task functions need from the robot model and the env options."""

    terrain: Terrain
    reward_weights: np.ndarray  # (K,) weights times the control period, in the task's reward order
    soft_limits: tuple[np.ndarray, np.ndarray]  # (12,) each: soft joint limits of the joint-limit term
    episode_steps: int
    task: LocomotionTask  # the robot and what its task observes and rewards


def task_constants(
    terrain: Terrain,
    joint_range: np.ndarray,
    reward_weights: np.ndarray,
    episode_steps: int,
    task: LocomotionTask | None = None,
) -> TaskConstants:
    """`TaskConstants` from the model's joint ranges (12, 2) and the unscaled reward weights (K,) of
    `task` (None: Zerith-1's, `HUMANOID_TASK`)."""
    task = HUMANOID_TASK if task is None else task
    centre, half = joint_range.mean(axis=1), 0.5 * (joint_range[:, 1] - joint_range[:, 0])
    soft = (centre - task.soft_limit * half, centre + task.soft_limit * half)
    return TaskConstants(terrain, reward_weights * task.robot.control_dt, soft, episode_steps, task)


class Judgement(NamedTuple):
    """A control step of n robots judged from the sensors after physics (`judge_step`)."""

    policy_obs: np.ndarray  # (n, POLICY_SIZE) float32
    critic_obs: np.ndarray  # (n, CRITIC_SIZE) float32
    terms: np.ndarray  # (n, K) weighted, dt-scaled reward terms, columns in REWARD_NAMES order
    reward: np.ndarray  # (n,)
    fall: np.ndarray  # (n,) bool
    lin_vel_error: np.ndarray  # (n,) |v_xy - v_xy_cmd|, m/s
    ang_vel_error: np.ndarray  # (n,) |yaw rate - commanded|, rad/s


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


class StepOutput(NamedTuple):
    """What one control step returns for n robots."""

    policy_obs: np.ndarray  # (n, POLICY_SIZE) float32
    critic_obs: np.ndarray  # (n, CRITIC_SIZE) float32
    reward: np.ndarray  # (n,)
    terminated: np.ndarray  # (n,) bool: a fall
    truncated: np.ndarray  # (n,) bool: time limit or unstable simulation
    fall: np.ndarray  # (n,) bool
    sim_unstable: np.ndarray  # (n,) bool
    lin_vel_error: np.ndarray  # (n,) |v_xy - v_xy_cmd|, m/s
    ang_vel_error: np.ndarray  # (n,) |yaw rate - commanded|, rad/s
    terms: np.ndarray  # (n, K) weighted, dt-scaled reward terms of this step, columns in REWARD_NAMES order


def step_output(
    e: Judgement,
    unstable: np.ndarray,
    step_count: np.ndarray,
    episode_steps: int,
    last_policy: np.ndarray,
    last_critic: np.ndarray,
) -> StepOutput:
    """The step's outcome: a fall terminates, the time limit or an unstable simulation truncates; an
    unstable robot keeps its last observations and gets no reward."""
    xp = namespace(e.reward, unstable)
    fall = e.fall & ~unstable
    column = unstable[:, None]
    return StepOutput(
        policy_obs=xp.where(column, last_policy, e.policy_obs),
        critic_obs=xp.where(column, last_critic, e.critic_obs),
        reward=xp.where(unstable, 0.0, e.reward),
        terminated=fall,
        truncated=((step_count >= episode_steps) | unstable) & ~fall,
        fall=fall,
        sim_unstable=unstable,
        lin_vel_error=e.lin_vel_error,
        ang_vel_error=e.ang_vel_error,
        terms=xp.where(column, 0.0, e.terms),
    )


class TaskState(NamedTuple):
    """The task state of n robots between control steps (leading axis n).

    One record for both backends: the CPU task (`ZerithTask.state`) keeps numpy arrays, replaced each step by
    `begin_step` and `end_step` and written in place only at resets; the MJX backend keeps JAX arrays
    inside its `MjxState`, replaced every step.
    """

    step_count: np.ndarray  # (n,) int, control steps into the episode
    force_offset: np.ndarray  # (n,) int, the force table's step at the episode's start
    gait_step: np.ndarray  # (n,) int, control steps into the gait cycle
    command: np.ndarray  # (n, 3)
    actions: np.ndarray  # (n, 3, 12) a_t, a_{t-1}, a_{t-2}
    joint_vel: np.ndarray  # (n, 12) at the last observation
    force: np.ndarray  # (n, 3) on each body of the force target
    domain_vector: np.ndarray  # (n, DOMAIN_VECTOR_SIZE)
    lags: np.ndarray  # (n, DECIMATION) int, control steps of delay of each physics sub-step
    policy_obs: np.ndarray  # (n, POLICY_SIZE) float32, the last observation
    critic_obs: np.ndarray  # (n, CRITIC_SIZE) float32
    feet_air_time: np.ndarray  # (n, feet) s since each foot last touched the ground (tasks that reward it)
    last_contact: np.ndarray  # (n, feet) bool, each foot's contact at the last step

    @staticmethod
    def zeros(n: int, task: LocomotionTask | None = None) -> TaskState:
        """The state of n robots of `task` (None: Zerith-1's) before their first reset (numpy)."""
        task = HUMANOID_TASK if task is None else task
        joints, feet = task.robot.num_joints, len(task.robot.foot_bodies)
        return TaskState(
            step_count=np.zeros(n, dtype=int),
            force_offset=np.zeros(n, dtype=int),
            gait_step=np.zeros(n, dtype=int),
            command=np.zeros((n, 3)),
            actions=np.zeros((n, 3, joints)),
            joint_vel=np.zeros((n, joints)),
            force=np.zeros((n, 3)),
            domain_vector=np.zeros((n, DOMAIN_VECTOR_SIZE)),
            lags=np.zeros((n, task.robot.decimation), dtype=int),
            policy_obs=np.zeros((n, task.policy_size), dtype=np.float32),
            critic_obs=np.zeros((n, task.critic_size), dtype=np.float32),
            feet_air_time=np.zeros((n, feet)),
            last_contact=np.zeros((n, feet), dtype=bool),
        )


def begin_step(
    state: TaskState,
    actions: np.ndarray,
    uniforms: np.ndarray,
    sc: ScenarioArrays,
    task: LocomotionTask | None = None,
) -> tuple[TaskState, Disturbances, np.ndarray]:
    """The first half of a control step, before physics, for both backends.

    From checked actions (n, 12) and the step's uniforms (n, draws.step) of `task` (None: Zerith-1's): the
    state with the new action history, force and command; the step's disturbances; the joint targets
    (n, 3, 12) of the last three actions (index = control steps of lag).
    """
    task = HUMANOID_TASK if task is None else task
    xp = namespace(actions, state.actions)
    history = xp.concatenate([actions[:, None], state.actions[:, :2]], axis=1)
    drawn = step_disturbances(
        uniforms, state.step_count, state.force_offset, state.force, state.command, sc, task.draws
    )
    state = state._replace(actions=history, force=drawn.force, command=drawn.command)
    return state, drawn, action_targets(history, task.robot)


def end_step(
    state: TaskState,
    readings: robot.Sensors,
    unstable: np.ndarray,
    noise: np.ndarray | None,
    constants: TaskConstants,
) -> tuple[TaskState, StepOutput]:
    """The second half of a control step, after physics, for both backends: the state one step on and the
    step's outcome, from the sensor readings (zeros where `unstable`) and the observation noise."""
    xp = namespace(state.step_count)
    step_count = state.step_count + 1
    gait_step = (state.gait_step + 1) % constants.task.gait_steps
    e, state = constants.task.judge(state, readings, gait_step, noise, constants)
    out = step_output(e, unstable, step_count, constants.episode_steps, state.policy_obs, state.critic_obs)
    state = state._replace(
        step_count=step_count,
        gait_step=gait_step,
        joint_vel=xp.array(readings.joint_vel),  # a copy: the readings may view the simulator's buffer
        policy_obs=out.policy_obs,
        critic_obs=out.critic_obs,
    )
    return state, out


Judge = Callable[
    [TaskState, Any, np.ndarray, "np.ndarray | None", TaskConstants], tuple[Judgement, TaskState]
]
"""(state before the step's end, sensor readings, gait step, noise, constants) -> the step judged, and the
state with the task's own fields (feet air time, last contact) moved on."""
Observe = Callable[[TaskState, Any, "np.ndarray | None", TaskConstants], tuple[np.ndarray, np.ndarray]]
"""(state of the robots just reset, their sensor readings, noise, constants) -> policy, critic obs."""


@dataclass(frozen=True, eq=False)
class LocomotionTask:
    """A robot's task: what it observes and is rewarded for, beside the step every robot shares.

    `begin_step`, `end_step`, `step_output`, the resets, disturbances and the physics are the same for
    every robot; each robot declares here its facts (`robot`), its observation sizes and noise, its reward
    terms, and the two functions that read its sensors: `judge` after each step, `observe` after a reset.
    """

    robot: RobotSpec
    policy_size: int
    critic_size: int
    noise_scale: np.ndarray
    """(policy_size,) half width of each policy entry's uniform training noise."""
    reward_weights: Mapping[str, float]
    """Each reward term's default weight, in the order of the reward columns."""
    judge: Judge
    observe: Observe
    critic_layout: tuple[tuple[str, int], ...]
    """The critic observation's (name, size) blocks; every task's has `base_linear_velocity`,
    `foot_contact` and its domain parameters last (`DomainParams.from_vector`'s layout)."""
    critic_offset: np.ndarray
    critic_scale: np.ndarray
    """The critic observation is `(value - critic_offset) * critic_scale` of each entry's physical value."""
    gait_steps: int = 1
    """Control steps in the gait clock's cycle (1: the task has no clock)."""
    soft_limit: float = JOINT_SOFT_LIMIT
    """Share of each joint's range (centred) beyond which the joint-limit penalty applies."""
    default_scenario: str = "train"
    """The scenario an env of this robot follows unless told otherwise."""

    def critic_in_units(self, critic: np.ndarray) -> np.ndarray:
        """Critic observations (..., critic_size) back in physical units."""
        return critic / self.critic_scale + self.critic_offset

    @cached_property
    def draws(self) -> Draws:
        return draw_layout(self.policy_size, self.robot.num_joints)

    @property
    def reward_names(self) -> tuple[str, ...]:
        return tuple(self.reward_weights)


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
    clock = GAIT_TABLE[state.gait_step]
    g = ground(r, c.terrain)
    return observations(
        r, g, clock, state.command, state.actions[:, 0], state.force, state.domain_vector, noise
    )


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
    gait_steps=len(GAIT_TABLE),
)
"""Zerith-1 walking with the paper's gait clock, observations and Table-4 rewards."""


class ZerithTask:
    """Task state of `num_robots` robots in one scenario, on numpy (the CPU backend); which robot and task:
    `constants.task`.

    Each robot has its own numpy random generator, drawing a fixed amount per reset and per step, so n
    robots stepped together follow exactly the trajectories of n single envs seeded alike.
    """

    def __init__(
        self,
        num_robots: int,
        scenario: Scenario,
        sensors: robot.Sensors,
        constants: TaskConstants,
        command: tuple[float, float, float] | None = None,
        first_robot: int = 0,
    ) -> None:
        n = self.num_robots = num_robots
        self.constants = constants
        self.tiles = TerrainLevels(constants.terrain.spec, np.arange(first_robot, first_robot + n))
        """Each robot's tile of the terrain, and the terrain curriculum's rule (`set_level_rule`)."""
        self.episode_steps = constants.episode_steps
        self.sensors = sensors
        self.task = constants.task
        self.draws = self.task.draws
        self.set_scenario(scenario, command)

        self.rngs: list[np.random.Generator] = [np.random.default_rng() for _ in range(n)]
        self.state = TaskState.zeros(n, self.task)
        """The robots' task state (numpy arrays, updated in place or replaced by the step)."""
        self._uniforms = np.zeros((n, self.draws.step))

    def set_scenario(self, scenario: Scenario, command: tuple[float, float, float] | None = None) -> None:
        """Follow `scenario` (and a fixed `command`, if given) from now on.

        Randomization ranges apply from each robot's next reset; the force schedule, pushes, observation
        noise and command draws from the next step. Nothing else changes: a curriculum can call it
        between rollouts.
        """
        self.scenario = scenario
        self.arrays = scenario_arrays(scenario, command, self.episode_steps, self.task.noise_scale)
        self._noisy = bool(self.arrays.noise_scale.any())

    # ----------------------------------------------------------------------------------------- reset
    def reset(self, ids: np.ndarray) -> tuple[DomainParams, np.ndarray]:
        """Start new episodes for robots `ids`, drawing from their generators.

        Returns their domain parameters (to apply to their models) and initial generalized positions
        (len(ids), 7 + 12) with the base height left at 0 (the caller places the feet on the ground).
        """
        ids = np.asarray(ids)
        u = np.empty((len(ids), self.draws.reset))
        for k, i in enumerate(ids.tolist()):
            self.rngs[i].random(out=u[k])
        spec = self.constants.terrain.spec
        start = reset_values(
            u, self.arrays, self.tiles.spawn_points(ids), spec.spawn_jitter, self.task.robot, self.draws
        )
        self.tiles.started(ids, start.qpos[:, :2])
        state = self.state
        state.domain_vector[ids] = start.domain_vector
        state.lags[ids] = start.lags
        state.command[ids] = start.command
        state.force_offset[ids] = start.force_offset
        self._uniforms[ids] = start.noise_uniforms  # the first observation's noise
        for started in (
            state.step_count,
            state.gait_step,
            state.actions,
            state.joint_vel,
            state.force,
            state.feet_air_time,
            state.last_contact,
        ):
            started[ids] = 0
        return DomainParams.from_vector(start.domain_vector), start.qpos

    def set_level_rule(self, rule: LevelRule | None) -> None:
        """Move robots between terrain levels by `rule` when their episodes end (None: stop); ValueError
        unless the terrain has tiles (`zerith_gym.terrain_levels`)."""
        self.tiles.set_rule(rule)

    def set_command(self, ids: np.ndarray, command: np.ndarray) -> None:
        """Override the current command of robots `ids` (until their next scheduled resampling)."""
        self.state.command[ids] = command

    # ------------------------------------------------------------------------------------- one step
    def before_physics(self, actions: np.ndarray) -> tuple[np.ndarray, Disturbances]:
        """Record actions (n, 12), already finite and clipped to [-1, 1]; draw this step's randomness.

        Returns the joint targets of the last three actions (n, 3, 12) (index = control steps of lag) and
        this step's disturbances: the external force (n, 3) and its target (n,), and base velocity kicks.
        """
        u = self._uniforms
        for rng, row in zip(self.rngs, u, strict=True):
            rng.random(out=row)
        self.state, drawn, targets = begin_step(self.state, actions, u, self.arrays, self.task)
        return targets, drawn

    def after_physics(self, sensordata: np.ndarray, unstable: np.ndarray) -> StepOutput:
        """Observations, rewards and episode ends from the sensors (n, nsensordata) after physics."""
        if np.logical_or.reduce(unstable):
            sensordata = np.where(unstable[:, None], 0.0, sensordata)
        readings = self.sensors.read(sensordata)
        noise = observation_noise(self._uniforms, self.arrays, self.draws) if self._noisy else None
        self.state, out = end_step(self.state, readings, unstable, noise, self.constants)
        ended = out.terminated | out.truncated
        self.tiles.record(readings.base_pos[:, :2], self.state.command, out.fall, ended, unstable)
        return out

    def observe(self, ids: np.ndarray, sensordata: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Policy and critic observations of robots `ids` right after their reset, from their sensors."""
        readings = self.sensors.read(sensordata)
        state = self.state
        noise = observation_noise(self._uniforms[ids], self.arrays, self.draws) if self._noisy else None
        started = TaskState(*(field[ids] for field in state))
        policy, critic = self.task.observe(started, readings, noise, self.constants)
        state.joint_vel[ids] = readings.joint_vel
        # New arrays: those of the last step were handed out (terminal observations of these robots).
        state = self.state = state._replace(
            policy_obs=state.policy_obs.copy(), critic_obs=state.critic_obs.copy()
        )
        state.policy_obs[ids], state.critic_obs[ids] = policy, critic
        return policy, critic


_FOOT_XY = np.array([0, 1, 3, 4])  # of a (left xyz, right xyz) row
_FOOT_Z = np.array([2, 5])
_FOOT_OF_SAMPLE = np.repeat([0, 1], len(HEIGHT_SAMPLE_OFFSETS))
_HIP_ROLL_YAW = np.array([0, 1, 6, 7])  # joints: left hip yaw, roll, right hip yaw, roll


def _yaw(heading: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Cosine and sine (n, 1) each of each robot's yaw, from its heading vector (n, 3)."""
    xp = namespace(heading)
    norm = xp.hypot(heading[:, 0:1], heading[:, 1:2]) + 1e-9
    return heading[:, 0:1] / norm, heading[:, 1:2] / norm
