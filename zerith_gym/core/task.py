"""The step every robot shares: resets, disturbances, the two halves of a control step, for a batch of robots.

The kernel's math is a set of pure functions over arrays with a leading robot axis, written against the
functions numpy and jax.numpy share (`zerith_gym.core.arrays`): `reset_values`, `step_disturbances`,
`action_targets`, `step_output`, and the two halves of a control step over one `TaskState` record,
`begin_step` and `end_step`. What a robot observes and is rewarded for is its `LocomotionTask`, called by
`end_step`: Zerith-1's in `zerith_gym.zerith1.task`, the quadruped's in `zerith_gym.go2like.task`.
Both backends call them: the CPU backend with numpy (`ZerithTask` below), the MJX backend with jax.numpy
under `jax.jit` (`zerith_gym.mjx`). What a scenario sets is handed to them as arrays (`ScenarioArrays`), so
a curriculum changes it without rebuilding anything.

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
from dataclasses import dataclass, field
from functools import cached_property
from typing import Any, NamedTuple

import numpy as np

from zerith_gym.core.arrays import namespace
from zerith_gym.core.commands import COMMAND_DRAWS, command_bounds, commands_from_uniforms
from zerith_gym.core.disturbances import FORCE_DRAWS, PUSH_DRAWS, horizontal_vectors, push_due
from zerith_gym.core.observations import layout_slices
from zerith_gym.core.randomization import (
    DOMAIN_DRAWS,
    DOMAIN_VECTOR_SIZE,
    DomainParams,
    delay_lags,
    domain_bounds,
    uniform_in,
)
from zerith_gym.core.scenarios import Scenario
from zerith_gym.core.spec import RobotSpec, read_sensors
from zerith_gym.terrain.ground import Terrain
from zerith_gym.terrain.levels import LevelRule, TerrainLevels

EPISODE_STEPS = 1000
"""Default control steps in an episode (20 s): reaching them is a truncation."""
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
    force_per_body: np.ndarray  # (2 episode_steps,) bool, each body of the target draws its own force
    force_offsets: np.ndarray  # (k,) int, the table steps an episode may start at (one drawn per episode)
    push_velocity: np.ndarray  # (2,) m/s
    command_low: np.ndarray  # (3,)
    command_high: np.ndarray  # (3,)
    standing_probability: np.ndarray  # ()
    fixed_command: np.ndarray  # (3,) the command of every episode where `has_fixed_command`
    has_fixed_command: np.ndarray  # () bool
    noise_scale: np.ndarray  # (policy size,) half width of the policy observation noise
    init_roll_pitch: np.ndarray  # () half width (rad) of the reset roll and pitch
    init_joint_scale: np.ndarray  # (2,) range of the factor on the default joint positions at reset


def scenario_arrays(
    scenario: Scenario,
    command: tuple[float, float, float] | None,
    episode_steps: int,
    task: LocomotionTask,
) -> ScenarioArrays:
    """The arrays of `scenario` (and of a fixed `command`, if any) for episodes of `episode_steps` of the
    robot of `task` (its control period, and its policy observation's training noise).

    The force table covers twice the episode, so that an episode may start anywhere in its first half
    (`ForceCycle.start_phases`); ValueError if the force program starts episodes later than that.
    """
    ranges, control_dt = scenario.randomization, task.robot.control_dt
    command_interval = round(scenario.command_ranges.resample_interval_s / control_dt)
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
            push_due(episode_steps, round(ranges.push_interval_s / control_dt), ranges.push_velocity),
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
        force_per_body=force.per_body,
        force_offsets=np.array(offsets, dtype=int),
        push_velocity=np.array(ranges.push_velocity, dtype=float),
        command_low=low,
        command_high=high,
        standing_probability=np.array(scenario.command_ranges.standing_probability),
        fixed_command=np.zeros(3) if command is None else np.asarray(command, dtype=float),
        has_fixed_command=np.array(command is not None),
        noise_scale=task.noise_scale * ranges.observation_noise,
        init_roll_pitch=np.array(ranges.init_roll_pitch, dtype=float),
        init_joint_scale=np.array(ranges.init_joint_scale, dtype=float),
    )


class ResetValues(NamedTuple):
    """A new episode's start of n robots, drawn by `reset_values`."""

    qpos: np.ndarray  # (n, 7 + 12) base position (height 0: the caller puts the feet on the ground), joints
    domain_vector: np.ndarray  # (n, DOMAIN_VECTOR_SIZE), the critic's layout (`DomainParams.from_vector`)
    lags: np.ndarray  # (n, decimation) control steps of delay of each physics sub-step's action
    command: np.ndarray  # (n, 3)
    noise_uniforms: np.ndarray  # (n, draws.step) the uniforms of the first observation's noise
    force_offset: np.ndarray  # (n,) int, the step of the force table the episode starts at


def reset_values(
    uniforms: np.ndarray,
    sc: ScenarioArrays,
    spawn_xy: np.ndarray,
    spawn_jitter: float,
    robot: RobotSpec,
    draws: Draws,
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


def action_targets(actions: np.ndarray, robot: RobotSpec) -> np.ndarray:
    """Joint targets (n, lags, 12) of an action history (n, lags, 12) within +-`robot.action_clip`, newest
    first."""
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
    draws: Draws,
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


def observation_noise(uniforms: np.ndarray, sc: ScenarioArrays, draws: Draws) -> np.ndarray:
    """The policy observation noise (n, policy size) from a step's uniforms (n, draws.step)."""
    return (2.0 * uniforms[:, draws.noise] - 1.0) * sc.noise_scale


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
    task: LocomotionTask,
) -> TaskConstants:
    """`TaskConstants` from the model's joint ranges (12, 2) and the unscaled reward weights (K,) of
    `task`."""
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
    inside its `MjxState`, replaced every step. The observation arrays are never written in place: a reset
    writes its robots' first observations into new arrays (`ZerithTask.observe`), so the arrays a step hands
    out (next and terminal observations) stay as they are, and the batch and the VecEnv pass them on
    without copies.
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
    def zeros(n: int, task: LocomotionTask) -> TaskState:
        """The state of n robots of `task` before their first reset (numpy)."""
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
    task: LocomotionTask,
) -> tuple[TaskState, Disturbances, np.ndarray]:
    """The first half of a control step, before physics, for both backends.

    From checked actions (n, 12) and the step's uniforms (n, draws.step) of `task`: the
    state with the new action history, force and command; the step's disturbances; the joint targets
    (n, 3, 12) of the last three actions (index = control steps of lag).
    """
    xp = namespace(actions, state.actions)
    history = xp.concatenate([actions[:, None], state.actions[:, :2]], axis=1)
    drawn = step_disturbances(
        uniforms, state.step_count, state.force_offset, state.force, state.command, sc, task.draws
    )
    state = state._replace(actions=history, force=drawn.force, command=drawn.command)
    return state, drawn, action_targets(history, task.robot)


def end_step(
    state: TaskState,
    readings: NamedTuple,
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
    policy_layout: tuple[tuple[str, int], ...]
    """The policy observation's (name, size) blocks."""
    deployment_notes: Mapping[str, str] = field(default_factory=dict)
    """How each policy block is measured on the robot (an exported actor's metadata tells a controller)."""
    deployment_extras: Mapping[str, Any] = field(default_factory=dict)
    """More of what a controller needs to build the observation (the gait clock, the height points)."""
    gait_steps: int = 1
    """Control steps in the gait clock's cycle (1: the task has no clock)."""
    soft_limit: float = JOINT_SOFT_LIMIT
    """Share of each joint's range (centred) beyond which the joint-limit penalty applies."""
    default_scenario: str = "train"
    """The scenario an env of this robot follows unless told otherwise."""
    policy_mirror: Any = None
    action_mirror: Any = None
    """Left-right mirror maps of the actor's observation and of an action (signed permutations, Zerith-1's
    `zerith_gym.zerith1.symmetry`), for a symmetry loss (`HuRiPPO(mirror_coef=...)`); None: none."""

    def critic_in_units(self, critic: np.ndarray) -> np.ndarray:
        """Critic observations (..., critic_size) back in physical units."""
        return critic / self.critic_scale + self.critic_offset

    @cached_property
    def draws(self) -> Draws:
        return draw_layout(self.policy_size, self.robot.num_joints)

    @property
    def reward_names(self) -> tuple[str, ...]:
        return tuple(self.reward_weights)


class ZerithTask:
    """Task state of `num_robots` robots in one scenario, on numpy (the CPU backend); which robot and task:
    `constants.task`.

    Each robot has its own numpy random generator, drawing a fixed amount per reset and per step, so n
    robots stepped together follow exactly the trajectories of n single envs seeded alike.

    A force schedule that draws per body (`ForceSchedule.per_body`) gives the target's first body the force
    drawn as above (the one the critic observes and `info["external_force"]` reports) and each other body
    its own, drawn from a generator of the robot's episode, seeded by the step's uniforms at its first
    per-body draw: the robot's own stream, and so everything else, is what it is without per-body draws.
    """

    def __init__(
        self,
        num_robots: int,
        scenario: Scenario,
        sensors: NamedTuple,
        constants: TaskConstants,
        command: tuple[float, float, float] | None = None,
        first_robot: int = 0,
    ) -> None:
        n = self.num_robots = num_robots
        self.constants = constants
        robots = np.arange(first_robot, first_robot + n)
        self.tiles = TerrainLevels(constants.terrain.spec, robots, constants.task.robot.control_dt)
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
        extra_bodies = max(len(bodies) for bodies in self.task.robot.force_bodies.values()) - 1
        self._own_forces = np.zeros((n, max(extra_bodies, 0), 3))  # the per-body draws of the later bodies
        self._body_rngs: list[np.random.Generator | None] = [None] * n
        self.other_forces: np.ndarray | None = None
        """(n, bodies - 1, 3) the force on each body of the target after the first during this step, or None
        where every body gets the first body's (the scenario never draws per body)."""

    def set_scenario(self, scenario: Scenario, command: tuple[float, float, float] | None = None) -> None:
        """Follow `scenario` (and a fixed `command`, if given) from now on.

        Randomization ranges apply from each robot's next reset; the force schedule, pushes, observation
        noise and command draws from the next step. Nothing else changes: a curriculum can call it
        between rollouts.
        """
        self.scenario = scenario
        self.arrays = scenario_arrays(scenario, command, self.episode_steps, self.task)
        self._noisy = bool(self.arrays.noise_scale.any())
        self._per_body = bool(self.arrays.force_per_body.any())

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
        self._own_forces[ids] = 0.0
        for i in ids.tolist():
            self._body_rngs[i] = None
        return DomainParams.from_vector(start.domain_vector), start.qpos

    def set_level_rule(self, rule: LevelRule | None) -> None:
        """Move robots between terrain levels by `rule` when their episodes end (None: stop); ValueError
        unless the terrain has tiles (`zerith_gym.terrain.levels`)."""
        self.tiles.set_rule(rule)

    def set_command(self, ids: np.ndarray, command: np.ndarray) -> None:
        """Override the current command of robots `ids` (until their next scheduled resampling)."""
        self.state.command[ids] = command

    # ------------------------------------------------------------------------------------- one step
    def before_physics(self, actions: np.ndarray) -> tuple[np.ndarray, Disturbances]:
        """Record actions (n, 12), finite and clipped to the action space; draw this step's randomness.

        Returns the joint targets of the last three actions (n, 3, 12) (index = control steps of lag) and
        this step's disturbances: the external force (n, 3) and its target (n,), and base velocity kicks.
        """
        u = self._uniforms
        for rng, row in zip(self.rngs, u, strict=True):
            rng.random(out=row)
        self.state, drawn, targets = begin_step(self.state, actions, u, self.arrays, self.task)
        self.other_forces = self._other_forces(drawn.force) if self._per_body else None
        return targets, drawn

    def _other_forces(self, force: np.ndarray) -> np.ndarray:
        """The force (n, bodies - 1, 3) on each body of the target after the first, which gets `force` (n, 3):
        `force` itself where the schedule draws one vector for the group, the body's own draw, redrawn and
        held as `force` is, where it draws per body."""
        sc, state = self.arrays, self.state
        at = state.step_count + state.force_offset
        per_body = sc.force_per_body[at]
        draw, on = sc.force_due[at, 0], sc.force_due[at, 1]
        own = self._own_forces
        bodies = own.shape[1]
        for i in np.flatnonzero(per_body & draw).tolist():
            rng = self._body_rngs[i]
            if rng is None:  # the episode's first per-body draw
                rng = self._body_rngs[i] = np.random.default_rng(self._uniforms[i].view(np.uint64))
            magnitude = np.broadcast_to(sc.force_magnitude[at[i]], (bodies, 2))
            own[i] = horizontal_vectors(
                rng.random((bodies, FORCE_DRAWS)), magnitude, np.full(bodies, sc.force_direction[at[i]])
            )
        own *= on[:, None, None]
        return np.where(per_body[:, None, None], own, force[:, None, :])

    def after_physics(self, sensordata: np.ndarray, unstable: np.ndarray) -> StepOutput:
        """Observations, rewards and episode ends from the sensors (n, nsensordata) after physics."""
        if np.logical_or.reduce(unstable):
            sensordata = np.where(unstable[:, None], 0.0, sensordata)
        readings = read_sensors(self.sensors, sensordata)
        noise = observation_noise(self._uniforms, self.arrays, self.draws) if self._noisy else None
        self.state, out = end_step(self.state, readings, unstable, noise, self.constants)
        ended = out.terminated | out.truncated
        self.tiles.record(readings.base_pos[:, :2], self.state.command, out.fall, ended, unstable)
        return out

    def observe(self, ids: np.ndarray, sensordata: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Policy and critic observations of robots `ids` right after their reset, from their sensors."""
        readings = read_sensors(self.sensors, sensordata)
        state = self.state
        noise = observation_noise(self._uniforms[ids], self.arrays, self.draws) if self._noisy else None
        started = TaskState(*(field[ids] for field in state))
        policy, critic = self.task.observe(started, readings, noise, self.constants)
        state.joint_vel[ids] = readings.joint_vel
        # New arrays: those of the last step were handed out (the step's observations, terminal ones of these
        # robots included), and whoever holds them may keep them (TaskState).
        state = self.state = state._replace(
            policy_obs=state.policy_obs.copy(), critic_obs=state.critic_obs.copy()
        )
        state.policy_obs[ids], state.critic_obs[ids] = policy, critic
        return policy, critic
