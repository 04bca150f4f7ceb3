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

from dataclasses import dataclass
from typing import NamedTuple

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
from zerith_gym.rewards import RewardInputs, reward_terms
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
    terms: np.ndarray  # (n, K) weighted, dt-scaled reward terms of this step, columns in REWARD_NAMES order


class _Ground(NamedTuple):
    """Heights above the ground under the robots (the terrain's height subtracted)."""

    base_height: np.ndarray  # (n,) pelvis
    foot_clearance: np.ndarray  # (n, 2) soles
    height_samples: np.ndarray  # (n, 18) soles above the ground at the sample points around each foot
    foot_contact: np.ndarray  # (n, 2) bool


class ZerithTask:
    """Task state and per-step logic of `num_robots` Zerith-1 robots in one scenario."""

    def __init__(
        self,
        num_robots: int,
        scenario: Scenario,
        terrain: Terrain,
        sensors: robot.Sensors,
        joint_range: np.ndarray,
        reward_weights: np.ndarray,
        command: tuple[float, float, float] | None = None,
        episode_steps: int = EPISODE_STEPS,
    ) -> None:
        n = self.num_robots = num_robots
        self.episode_steps = episode_steps
        self.terrain = terrain
        self.reward_weights = reward_weights * robot.CONTROL_DT
        centre, half = joint_range.mean(axis=1), 0.5 * (joint_range[:, 1] - joint_range[:, 0])
        self.soft_low = centre - JOINT_SOFT_LIMIT * half
        self.soft_high = centre + JOINT_SOFT_LIMIT * half
        self.set_scenario(scenario, command)
        self.gait_table = gait.cycle_table(robot.CONTROL_DT)
        self.sensors = sensors
        self._half_stance = np.array([0.5 * robot.HIP_WIDTH, -0.5 * robot.HIP_WIDTH])

        self.rngs: list[np.random.Generator] = [np.random.default_rng() for _ in range(n)]
        self.step_count = np.zeros(n, dtype=int)
        self.gait_step = np.zeros(n, dtype=int)  # control steps into the gait cycle
        self.command = np.zeros((n, 3))
        self.actions = np.zeros((n, 3, robot.NUM_JOINTS))  # a_t, a_{t-1}, a_{t-2}
        self.joint_vel = np.zeros((n, robot.NUM_JOINTS))
        self.force = np.zeros((n, 3))
        self.domain_vector = np.zeros((n, DOMAIN_VECTOR_SIZE))
        self.lags = np.zeros((n, robot.DECIMATION), dtype=int)
        self.policy_obs = np.zeros((n, POLICY_SIZE), dtype=np.float32)
        self.critic_obs = np.zeros((n, CRITIC_SIZE), dtype=np.float32)
        self._uniforms = np.zeros((n, STEP_DRAWS))

    def set_scenario(self, scenario: Scenario, command: tuple[float, float, float] | None = None) -> None:
        """Follow `scenario` (and a fixed `command`, if given) from now on.

        Randomization ranges apply from each robot's next reset; the force schedule, pushes, observation
        noise and command draws from the next step. Nothing else changes: a curriculum can call it
        between rollouts.
        """
        self.scenario = scenario
        self.ranges = scenario.randomization
        self.fixed_command = None if command is None else np.asarray(command, dtype=float)
        self.noise_scale = policy_noise_scale() * self.ranges.observation_noise
        self._noisy = bool(self.noise_scale.any())
        self._domain_bounds = domain_bounds(self.ranges)
        # What is due at each control step of an episode: force draw, force on, command draw, push.
        command_interval = round(scenario.command_ranges.resample_interval_s / robot.CONTROL_DT)
        steps = np.arange(self.episode_steps)
        self._due = np.column_stack(
            [
                *schedule_table(scenario.force, self.episode_steps),
                (steps > 0) & (steps % command_interval == 0) & (self.fixed_command is None),
                push_due(
                    self.episode_steps,
                    round(self.ranges.push_interval_s / robot.CONTROL_DT),
                    self.ranges.push_velocity,
                ),
            ]
        )

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
        every = slice(None)
        readings = self.sensors.read(sensordata)
        clock = self.gait_table[self.gait_step]  # (n, 8), see gait.cycle_table
        ground = self._ground(readings)
        terms = reward_terms(self._reward_inputs(every, readings, ground, clock))
        terms *= self.reward_weights
        policy, critic = self._observations(every, readings, ground, clock)
        self.joint_vel[:] = readings.joint_vel  # a copy: the readings view the simulator's buffer
        reward = np.add.reduce(terms, axis=1)
        fall = self._falls(readings, ground) & ~unstable
        truncated = ((self.step_count >= self.episode_steps) | unstable) & ~fall
        if any_unstable:
            policy[unstable] = self.policy_obs[unstable]
            critic[unstable] = self.critic_obs[unstable]
            terms[unstable] = 0.0
            reward[unstable] = 0.0
        self.policy_obs, self.critic_obs = policy, critic
        linvel, angvel, command = readings.base_linvel, readings.base_angvel, self.command
        velocity_error = linvel[:, :2] - command[:, :2]
        return StepOutput(
            policy_obs=policy,
            critic_obs=critic,
            reward=reward,
            terminated=fall,
            truncated=truncated,
            fall=fall,
            sim_unstable=unstable,
            lin_vel_error=np.hypot(velocity_error[:, 0], velocity_error[:, 1]),
            ang_vel_error=np.abs(angvel[:, 2] - command[:, 2]),
            terms=terms,
        )

    def observe(self, ids: np.ndarray, sensordata: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Policy and critic observations of robots `ids` right after their reset, from their sensors."""
        readings = self.sensors.read(sensordata)
        clock = self.gait_table[self.gait_step[ids]]
        policy, critic = self._observations(ids, readings, self._ground(readings), clock)
        self.joint_vel[ids] = readings.joint_vel
        # New arrays: those of the last step were handed out (terminal observations of these robots).
        self.policy_obs, self.critic_obs = self.policy_obs.copy(), self.critic_obs.copy()
        self.policy_obs[ids], self.critic_obs[ids] = policy, critic
        return policy, critic

    # ----------------------------------------------------------------- from sensor readings (no state change)
    def _ground(self, r: robot.Sensors) -> _Ground:
        """Pelvis and soles above the ground under them, and which feet touch it."""
        foot_z = r.foot_pos[:, _FOOT_Z]
        if self.terrain.is_plane:
            base_height = r.base_pos[:, 2]
            foot_clearance = foot_z
            height_samples = foot_z[:, _FOOT_OF_SAMPLE]  # the sole height at every sample point
        else:
            n = len(foot_z)
            base_height = r.base_pos[:, 2] - self.terrain.height_at(r.base_pos[:, :2])
            feet_xy = r.foot_pos[:, _FOOT_XY].reshape(n, 2, 2)
            foot_clearance = foot_z - self.terrain.height_at(feet_xy)
            cos_yaw, sin_yaw = _yaw(r.base_heading)
            x, y = HEIGHT_SAMPLE_OFFSETS[:, 0], HEIGHT_SAMPLE_OFFSETS[:, 1]
            offsets = np.stack([cos_yaw * x - sin_yaw * y, sin_yaw * x + cos_yaw * y], axis=-1)  # (n, 9, 2)
            points = feet_xy[:, :, None, :] + offsets[:, None]  # (n, 2, 9, 2)
            height_samples = (foot_z[:, :, None] - self.terrain.height_at(points)).reshape(n, -1)
        foot_contact = r.foot_force[:, _FOOT_Z] > CONTACT_THRESHOLD
        return _Ground(base_height, foot_clearance, height_samples, foot_contact)

    def _observations(
        self, sel: slice | np.ndarray, r: robot.Sensors, ground: _Ground, clock: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """Policy (noisy where the scenario says so) and critic observations (float32) of robots `sel`."""
        up = r.base_up
        policy = np.concatenate(
            [
                np.arctan2(up[:, 1:2], up[:, 2:3]),  # roll
                np.arcsin(np.minimum(np.maximum(-up[:, 0:1], -1.0), 1.0)),  # pitch
                r.base_angvel,
                clock[:, 0:2],
                self.command[sel],
                r.joint_pos - robot.DEFAULT_JOINT_POS,
                r.joint_vel,
                self.actions[sel, 0],
            ],
            axis=1,
        )
        critic = np.concatenate(
            [
                policy,
                r.base_linvel,
                ground.base_height[:, None],
                ground.height_samples,
                ground.foot_contact,
                r.foot_force,
                clock[:, 2:4],  # desired contacts
                self.force[sel],
                self.domain_vector[sel],
            ],
            axis=1,
            dtype=np.float32,
        )
        if self._noisy:
            policy += (2.0 * self._uniforms[sel, _NOISE] - 1.0) * self.noise_scale
        return policy.astype(np.float32), critic

    def _reward_inputs(
        self, sel: slice | np.ndarray, r: robot.Sensors, ground: _Ground, clock: np.ndarray
    ) -> RewardInputs:
        """What the reward terms of robots `sel` read (zerith_gym.rewards)."""
        command, actions, foot_pos = self.command[sel], self.actions[sel], r.foot_pos
        # Feet relative to the base, in the base's yaw frame, against the Raibert targets.
        cos_yaw, sin_yaw = _yaw(r.base_heading)
        rel_x = foot_pos[:, 0::3] - r.base_pos[:, 0:1]
        rel_y = foot_pos[:, 1::3] - r.base_pos[:, 1:2]
        shift = clock[:, 6:8]  # Raibert: feet ahead/behind the hips by shift * commanded velocity
        raibert_error = np.concatenate(
            [
                cos_yaw * rel_x + sin_yaw * rel_y - shift * command[:, 0:1],
                cos_yaw * rel_y - sin_yaw * rel_x - shift * command[:, 1:2] - self._half_stance,
            ],
            axis=1,
        )
        joint_pos, joint_vel = r.joint_pos, r.joint_vel
        return RewardInputs(
            command=command,
            base_linvel=r.base_linvel,
            base_angvel=r.base_angvel,
            base_up=r.base_up,
            height_error=ground.base_height - robot.STANDING_HEIGHT,
            joint_vel=joint_vel,
            joint_acc=(joint_vel - self.joint_vel[sel]) * (1.0 / robot.CONTROL_DT),
            torques=r.joint_torque,
            outside_limits=np.logical_or.reduce(
                (joint_pos < self.soft_low) | (joint_pos > self.soft_high), axis=1
            ),
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

    @staticmethod
    def _falls(r: robot.Sensors, ground: _Ground) -> np.ndarray:
        """Which robots fell: pelvis too low above the ground or tilted too far."""
        return (ground.base_height < FALL_HEIGHT) | (r.base_up[:, 2] < _COS_FALL_TILT)


_FOOT_XY = np.array([0, 1, 3, 4])  # of a (left xyz, right xyz) row
_FOOT_Z = np.array([2, 5])
_FOOT_OF_SAMPLE = np.repeat([0, 1], len(HEIGHT_SAMPLE_OFFSETS))
_HIP_ROLL_YAW = np.array([0, 1, 6, 7])  # joints: left hip yaw, roll, right hip yaw, roll


def _yaw(heading: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Cosine and sine (n, 1) each of each robot's yaw, from its heading vector (n, 3)."""
    norm = np.hypot(heading[:, 0:1], heading[:, 1:2]) + 1e-9
    return heading[:, 0:1] / norm, heading[:, 1:2] / norm
