"""The Zerith1-v0 task for a batch of robots: numpy over a leading axis, one random generator per robot.

`ZerithTask` holds the task state of n robots (gait clock, commands, action history, external forces,
sampled domain parameters) and turns physics readings into observations, rewards and episode ends.
It never touches MuJoCo: the caller steps the physics. Per control step:

1. `before_physics(actions)` -> joint targets per delay lag, the external force, optional velocity kicks;
2. the caller runs `decimation` physics steps (sub-step j of robot i applies `targets[i, lags[i, j]]`);
3. `after_physics(sensordata, unstable)` -> observations, rewards, terminations, truncations, infos.

Each robot consumes a fixed amount of randomness per reset and per step from its own generator, so n
robots stepped together follow exactly the trajectories of n single environments seeded alike.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np

from zerith_gym import gait, robot
from zerith_gym.commands import COMMAND_DRAWS, sample_commands
from zerith_gym.disturbances import (
    FORCE_DRAWS,
    PUSH_DRAWS,
    horizontal_vectors,
    push_due,
    schedule_table,
    update_forces,
)
from zerith_gym.observations import (
    CRITIC_LAYOUT,
    CRITIC_SIZE,
    HEIGHT_SAMPLE_OFFSETS,
    POLICY_LAYOUT,
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
from zerith_gym.rewards import REWARD_NAMES, reward_terms
from zerith_gym.scenarios import Scenario
from zerith_gym.terrain import Terrain

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

_NOISE = slice(0, POLICY_SIZE)
_FORCE = slice(_NOISE.stop, _NOISE.stop + FORCE_DRAWS)
_COMMAND = slice(_FORCE.stop, _FORCE.stop + COMMAND_DRAWS)
_PUSH = slice(_COMMAND.stop, _COMMAND.stop + PUSH_DRAWS)
STEP_DRAWS = _PUSH.stop
"""Uniform numbers each robot draws per control step, used or not, to keep streams aligned."""
_RESET = layout_slices(
    (
        ("domain", DOMAIN_DRAWS),
        ("joint_scale", robot.NUM_JOINTS),
        ("roll_pitch", 2),
        ("spawn", 2),
        ("command", COMMAND_DRAWS),
        ("step", STEP_DRAWS),
    )
)
RESET_DRAWS = _RESET["step"].stop
"""Uniform numbers each robot draws per reset, in the order of `_RESET`."""
_COS_FALL_TILT = float(np.cos(FALL_TILT))
_P = layout_slices(POLICY_LAYOUT)
_C = layout_slices(CRITIC_LAYOUT)
_DOMAIN = slice(_C["domain_friction"].start, CRITIC_SIZE)


@dataclass
class _Evaluation:
    policy: np.ndarray
    critic: np.ndarray
    terms: np.ndarray | None
    qvel: np.ndarray
    base_height: np.ndarray
    up_z: np.ndarray
    lin_vel_error: np.ndarray
    ang_vel_error: np.ndarray


@dataclass
class StepOutput:
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
    terms: np.ndarray  # (n, K) weighted, dt-scaled reward terms of this step


class ZerithTask:
    """Task state and per-step logic of `num_robots` Zerith-1 robots in one scenario."""

    def __init__(
        self,
        num_robots: int,
        scenario: Scenario,
        terrain: Terrain,
        sensors: dict[str, slice],
        joint_range: np.ndarray,
        reward_weights: np.ndarray,
        command: tuple[float, float, float] | None = None,
        episode_steps: int = EPISODE_STEPS,
    ) -> None:
        n = self.num_robots = num_robots
        self.episode_steps = episode_steps
        self.scenario = scenario
        self.ranges = scenario.randomization
        self.terrain = terrain
        self.fixed_command = None if command is None else np.asarray(command, dtype=float)
        self.reward_weights = reward_weights * robot.CONTROL_DT
        centre, half = joint_range.mean(axis=1), 0.5 * (joint_range[:, 1] - joint_range[:, 0])
        self.soft_low = centre - JOINT_SOFT_LIMIT * half
        self.soft_high = centre + JOINT_SOFT_LIMIT * half
        self.noise_scale = policy_noise_scale() * self.ranges.observation_noise
        self._noisy = bool(self.noise_scale.any())
        # What is due at each control step of an episode: force draw, force on, command draw, push.
        command_interval = round(scenario.command_ranges.resample_interval_s / robot.CONTROL_DT)
        steps = np.arange(episode_steps)
        self._due = np.column_stack(
            [
                *schedule_table(scenario.force, episode_steps),
                (steps > 0) & (steps % command_interval == 0) & (self.fixed_command is None),
                push_due(
                    episode_steps,
                    round(self.ranges.push_interval_s / robot.CONTROL_DT),
                    self.ranges.push_velocity,
                ),
            ]
        )
        self.gait_table = gait.cycle_table(robot.CONTROL_DT)
        self._sensor_views(sensors)

        self.rngs: list[np.random.Generator] = [np.random.default_rng() for _ in range(n)]
        self.step_count = np.zeros(n, dtype=int)
        self.gait_step = np.zeros(n, dtype=int)  # control steps into the gait cycle
        self.command = np.zeros((n, 3))
        self.actions = np.zeros((n, 3, robot.NUM_JOINTS))  # a_t, a_{t-1}, a_{t-2}
        self.joint_vel = np.zeros((n, robot.NUM_JOINTS))
        self.force = np.zeros((n, 3))
        self._domain_bounds = domain_bounds(self.ranges)
        self.domain_vector = np.zeros((n, DOMAIN_VECTOR_SIZE))
        self.domain = DomainParams.from_vector(self.domain_vector)  # views of domain_vector
        self.lags = np.zeros((n, robot.DECIMATION), dtype=int)
        self.episode_sums = np.zeros((n, len(REWARD_NAMES)))
        self.policy_obs = np.zeros((n, POLICY_SIZE), dtype=np.float32)
        self.critic_obs = np.zeros((n, CRITIC_SIZE), dtype=np.float32)
        self._uniforms = np.zeros((n, STEP_DRAWS))

    def _sensor_views(self, sensors: dict[str, slice]) -> None:
        """Slices of sensordata for each quantity; sensors of one quantity are contiguous in the MJCF."""

        def block(*names: str) -> slice:
            parts = [sensors[name] for name in names]
            if any(a.stop != b.start for a, b in itertools.pairwise(parts)):
                raise ValueError(f"sensors {names} must be contiguous in the model")
            return slice(parts[0].start, parts[-1].stop)

        joints, feet = robot.JOINT_NAMES, ("left_foot", "right_foot")
        self._s_base_pos = block("base_pos")
        self._s_heading = block("base_heading")
        self._s_base_up = block("base_up")
        self._s_linvel = block("base_linvel")
        self._s_angvel = block("base_angvel")
        self._s_qpos = block(*(f"{j}_pos" for j in joints))
        self._s_qvel = block(*(f"{j}_vel" for j in joints))
        self._s_torque = block(*(f"{j}_torque" for j in joints))
        self._s_foot_pos = block(*(f"{f}_pos" for f in feet))
        self._s_foot_up = block(*(f"{f}_up" for f in feet))
        self._s_foot_vel = block(*(f"{f}_linvel" for f in feet))
        self._s_foot_force = block(*(f"{f}_force" for f in feet))
        self._s_collision = sensors["leg_collision"].start
        self._hip_roll_yaw = np.array([0, 1, 6, 7])
        self._xy_of_two = np.array([0, 1, 3, 4])
        self._z_of_two = np.array([2, 5])
        self._foot_of_sample = np.repeat([0, 1], len(HEIGHT_SAMPLE_OFFSETS))
        self._half_stance = np.array([0.5 * robot.HIP_WIDTH, -0.5 * robot.HIP_WIDTH])

    # ----------------------------------------------------------------------------------------- reset
    def reset(self, ids: np.ndarray) -> tuple[DomainParams, np.ndarray]:
        """Start new episodes for robots `ids`, drawing from their generators.

        Returns their domain parameters (to apply to their models) and initial generalized positions
        (len(ids), 7 + 12) with the base height left at 0 (the caller places the feet on the ground).
        """
        ids = np.asarray(ids)
        ranges, terrain = self.ranges, self.terrain.spec
        u = np.empty((len(ids), RESET_DRAWS))
        for k, i in enumerate(ids.tolist()):
            self.rngs[i].random(out=u[k])
        half_roll_pitch = uniform_in((-1.0, 1.0), u[:, _RESET["roll_pitch"]]) * ranges.init_roll_pitch / 2
        (cr, cp), (sr, sp) = np.cos(half_roll_pitch).T, np.sin(half_roll_pitch).T
        spawn = uniform_in((-1.0, 1.0), u[:, _RESET["spawn"]]) * terrain.spawn_jitter
        joint_scale = uniform_in(ranges.init_joint_scale, u[:, _RESET["joint_scale"]])
        qpos = np.column_stack(
            [
                terrain.spawn_xy + spawn,
                np.zeros(len(ids)),
                cp * cr,
                cp * sr,
                sp * cr,
                -sp * sr,
                robot.DEFAULT_JOINT_POS * joint_scale,
            ]
        )
        domain_vector = uniform_in(self._domain_bounds, u[:, _RESET["domain"]])
        self.domain_vector[ids] = domain_vector
        domain = DomainParams.from_vector(domain_vector)
        self.lags[ids] = delay_lags(domain.action_delay, robot.PHYSICS_DT, robot.DECIMATION)
        if self.fixed_command is None:
            self.command[ids] = sample_commands(u[:, _RESET["command"]], self.scenario.command_ranges)
        else:
            self.command[ids] = self.fixed_command
        self._uniforms[ids] = u[:, _RESET["step"]]  # the first observation's noise
        self.step_count[ids] = 0
        self.gait_step[ids] = 0
        self.actions[ids] = 0.0
        self.joint_vel[ids] = 0.0
        self.force[ids] = 0.0
        self.episode_sums[ids] = 0.0
        return domain, qpos

    def set_command(self, ids: np.ndarray, command: np.ndarray) -> None:
        """Override the current command of robots `ids` (until their next scheduled resampling)."""
        self.command[ids] = command

    # ------------------------------------------------------------------------------------- one step
    def before_physics(self, actions: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
        """Record actions (n, 12), already finite and clipped to [-1, 1]; draw this step's randomness.

        Returns the joint targets of the last three actions (n, 3, 12) (index = control steps of lag),
        the external force (n, 3) on the scenario's target bodies, and base velocity kicks (n, 2) or None.
        """
        self.actions[:, 1:] = self.actions[:, :-1]
        self.actions[:, 0] = actions
        targets = robot.DEFAULT_JOINT_POS + robot.ACTION_SCALE * self.actions
        u = self._uniforms
        for rng, row in zip(self.rngs, u, strict=True):
            rng.random(out=row)
        due = self._due[self.step_count]
        _, _, command_due, push_due = np.logical_or.reduce(due, axis=0).tolist()
        self.force = update_forces(
            due[:, 0], due[:, 1], u[:, _FORCE], self.force, self.scenario.force.magnitude
        )
        if command_due:
            self.command[due[:, 2]] = sample_commands(u[due[:, 2], _COMMAND], self.scenario.command_ranges)
        kicks = None
        if push_due:
            kicks = horizontal_vectors(u[:, _PUSH], self.ranges.push_velocity)[:, :2] * due[:, 3:4]
        return targets, self.force, kicks

    def after_physics(self, sensordata: np.ndarray, unstable: np.ndarray) -> StepOutput:
        """Observations, rewards and episode ends from the sensors (n, nsensordata) after physics."""
        self.step_count += 1
        self.gait_step = (self.gait_step + 1) % len(self.gait_table)
        any_unstable = bool(np.logical_or.reduce(unstable))
        if any_unstable:
            sensordata = np.where(unstable[:, None], 0.0, sensordata)
        ev = self._evaluate(slice(None), sensordata, with_rewards=True)
        self.joint_vel[:] = ev.qvel  # a copy: `ev.qvel` may view the simulator's sensordata
        terms = ev.terms
        reward = np.add.reduce(terms, axis=1)
        policy, critic = ev.policy, ev.critic
        fall = ((ev.base_height < FALL_HEIGHT) | (ev.up_z < _COS_FALL_TILT)) & ~unstable
        truncated = ((self.step_count >= self.episode_steps) | unstable) & ~fall
        if any_unstable:
            policy[unstable] = self.policy_obs[unstable]
            critic[unstable] = self.critic_obs[unstable]
            terms[unstable] = 0.0
            reward[unstable] = 0.0
        self.policy_obs, self.critic_obs = policy, critic
        self.episode_sums += terms
        return StepOutput(
            policy_obs=policy,
            critic_obs=critic,
            reward=reward,
            terminated=fall,
            truncated=truncated,
            fall=fall,
            sim_unstable=unstable,
            lin_vel_error=ev.lin_vel_error,
            ang_vel_error=ev.ang_vel_error,
            terms=terms,
        )

    def observe(self, ids: np.ndarray, sensordata: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Policy and critic observations of robots `ids` right after their reset, from their sensors."""
        ev = self._evaluate(ids, sensordata, with_rewards=False)
        self.joint_vel[ids] = ev.qvel
        self.policy_obs[ids], self.critic_obs[ids] = ev.policy, ev.critic
        return ev.policy, ev.critic

    def _evaluate(self, sel: slice | np.ndarray, s: np.ndarray, with_rewards: bool) -> _Evaluation:
        """Everything computed from the sensors `s` of robots `sel`; changes no state."""
        n = len(s)
        command, actions = self.command[sel], self.actions[sel]
        clock = self.gait_table[self.gait_step[sel]]  # (n, 8), see gait.cycle_table
        stance = clock[:, 2:4]
        base_pos, heading, up = s[:, self._s_base_pos], s[:, self._s_heading], s[:, self._s_base_up]
        linvel, angvel = s[:, self._s_linvel], s[:, self._s_angvel]
        qpos, qvel = s[:, self._s_qpos], s[:, self._s_qvel]
        foot_pos = s[:, self._s_foot_pos]  # (n, 6): left xyz, right xyz
        foot_force = s[:, self._s_foot_force]
        foot_z = foot_pos[:, self._z_of_two]

        if self.terrain.is_plane:
            base_height = base_pos[:, 2]
            foot_clearance = foot_z
            height_samples = foot_z[:, self._foot_of_sample]  # the sole height at every sample point
        else:
            base_height = base_pos[:, 2] - self.terrain.height_at(base_pos[:, :2])
            feet_xy = foot_pos[:, self._xy_of_two].reshape(n, 2, 2)
            foot_clearance = foot_z - self.terrain.height_at(feet_xy)
            points = feet_xy[:, :, None, :] + _rotate(HEIGHT_SAMPLE_OFFSETS, heading)[:, None]  # (n, 2, 9, 2)
            height_samples = (foot_z[:, :, None] - self.terrain.height_at(points)).reshape(n, -1)

        foot_contact = foot_force[:, self._z_of_two] > CONTACT_THRESHOLD
        joint_offset = qpos - robot.DEFAULT_JOINT_POS

        terms = None
        if with_rewards:
            # Feet relative to the base, in the base's yaw frame, against the Raibert targets.
            norm = np.hypot(heading[:, 0:1], heading[:, 1:2]) + 1e-9
            cos_yaw, sin_yaw = heading[:, 0:1] / norm, heading[:, 1:2] / norm
            rel_x = foot_pos[:, 0::3] - base_pos[:, 0:1]
            rel_y = foot_pos[:, 1::3] - base_pos[:, 1:2]
            shift = clock[:, 6:8]  # Raibert: feet ahead/behind the hips by shift * commanded velocity
            raibert_error = np.concatenate(
                [
                    cos_yaw * rel_x + sin_yaw * rel_y - shift * command[:, 0:1],
                    cos_yaw * rel_y - sin_yaw * rel_x - shift * command[:, 1:2] - self._half_stance,
                ],
                axis=1,
            )  # x left, x right, y left, y right
            terms = reward_terms(
                command=command,
                base_linvel=linvel,
                base_angvel=angvel,
                base_up=up,
                height_error=base_height - robot.STANDING_HEIGHT,
                joint_vel=qvel,
                joint_acc=(qvel - self.joint_vel[sel]) * (1.0 / robot.CONTROL_DT),
                torques=s[:, self._s_torque],
                outside_limits=np.logical_or.reduce((qpos < self.soft_low) | (qpos > self.soft_high), axis=1),
                hip_roll_yaw=joint_offset[:, self._hip_roll_yaw],
                foot_up_z=s[:, self._s_foot_up][:, self._z_of_two],
                foot_speed_xy=s[:, self._s_foot_vel][:, self._xy_of_two],
                foot_force=foot_force,
                foot_contact=foot_contact,
                swing_height_error=foot_clearance - clock[:, 4:6],
                raibert_error=raibert_error,
                stance=stance,
                leg_collision=s[:, self._s_collision] > 0,
                action=actions[:, 0],
                last_action=actions[:, 1],
                last_last_action=actions[:, 2],
            )
            terms *= self.reward_weights

        policy = np.concatenate(
            [
                np.arctan2(up[:, 1:2], up[:, 2:3]),  # roll
                np.arcsin(np.minimum(np.maximum(-up[:, 0:1], -1.0), 1.0)),  # pitch
                angvel,
                clock[:, 0:2],
                command,
                joint_offset,
                qvel,
                actions[:, 0],
            ],
            axis=1,
        )
        critic = np.concatenate(
            [
                policy,
                linvel,
                base_height[:, None],
                height_samples,
                foot_contact,
                foot_force,
                stance,
                self.force[sel],
                self.domain_vector[sel],
            ],
            axis=1,
            dtype=np.float32,
        )
        if self._noisy:
            policy += (2.0 * self._uniforms[sel, _NOISE] - 1.0) * self.noise_scale
        velocity_error = linvel[:, :2] - command[:, :2]
        return _Evaluation(
            policy=policy.astype(np.float32),
            critic=critic,
            terms=terms,
            qvel=qvel,
            base_height=base_height,
            up_z=up[:, 2],
            lin_vel_error=np.hypot(velocity_error[:, 0], velocity_error[:, 1]),
            ang_vel_error=np.abs(angvel[:, 2] - command[:, 2]),
        )

    def episode_terms(self, i: int) -> dict[str, float]:
        """Per-term sums of the weighted rewards over robot i's episode so far."""
        return dict(zip(REWARD_NAMES, self.episode_sums[i].tolist(), strict=True))


def _rotate(xy: np.ndarray, heading: np.ndarray, inverse: bool = False) -> np.ndarray:
    """Rotate points xy (..., 2) by each robot's yaw (given by its heading vector (n, 3)), or by minus it.

    `xy` is (k, 2) (the same points for every robot) or (n, k, 2); the result is (n, k, 2).
    """
    norm = np.hypot(heading[:, 0], heading[:, 1]) + 1e-9
    c = (heading[:, 0] / norm)[:, None]
    s = (heading[:, 1] / norm)[:, None]
    if inverse:
        s = -s
    x, y = xy[..., 0], xy[..., 1]
    return np.stack([c * x - s * y, s * x + c * y], axis=-1)
