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

import numpy as np

from zerith_gym import gait, robot
from zerith_gym.commands import COMMAND_DRAWS, sample_commands
from zerith_gym.disturbances import FORCE_DRAWS, PUSH_DRAWS, push_kicks, update_forces
from zerith_gym.observations import (
    CRITIC_LAYOUT,
    CRITIC_SIZE,
    HEIGHT_SAMPLE_OFFSETS,
    POLICY_LAYOUT,
    POLICY_SIZE,
    layout_slices,
    policy_noise_scale,
)
from zerith_gym.randomization import DomainParams, delay_lags, sample_domain
from zerith_gym.rewards import REWARD_NAMES, reward_terms
from zerith_gym.scenarios import Scenario
from zerith_gym.terrain import Terrain

EPISODE_STEPS = 1000
"""Control steps in an episode (20 s): reaching it is a truncation."""
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
    ) -> None:
        n = self.num_robots = num_robots
        self.scenario = scenario
        self.ranges = scenario.randomization
        self.terrain = terrain
        self.fixed_command = None if command is None else np.asarray(command, dtype=float)
        self.reward_weights = reward_weights * robot.CONTROL_DT
        centre, half = joint_range.mean(axis=1), 0.5 * (joint_range[:, 1] - joint_range[:, 0])
        self.soft_low = centre - JOINT_SOFT_LIMIT * half
        self.soft_high = centre + JOINT_SOFT_LIMIT * half
        self.noise_scale = policy_noise_scale() * self.ranges.observation_noise
        self.command_interval = round(scenario.command_ranges.resample_interval_s / robot.CONTROL_DT)
        self.push_interval = round(self.ranges.push_interval_s / robot.CONTROL_DT)
        self._phase_step = robot.CONTROL_DT / gait.GAIT_PERIOD
        self._sensor_views(sensors)

        self.rngs: list[np.random.Generator] = [np.random.default_rng() for _ in range(n)]
        self.step_count = np.zeros(n, dtype=int)
        self.phase = np.zeros(n)
        self.command = np.zeros((n, 3))
        self.actions = np.zeros((n, 3, robot.NUM_JOINTS))  # a_t, a_{t-1}, a_{t-2}
        self.joint_vel = np.zeros((n, robot.NUM_JOINTS))
        self.force = np.zeros((n, 3))
        self.domain = DomainParams.stack([sample_domain(np.random.default_rng(0), self.ranges)] * n)
        self.domain_vector = self.domain.as_vector()
        self.lags = np.zeros((n, robot.DECIMATION), dtype=int)
        self.episode_sums = np.zeros((n, len(REWARD_NAMES)))
        self.policy_obs = np.zeros((n, POLICY_SIZE), dtype=np.float32)
        self.critic_obs = np.zeros((n, CRITIC_SIZE), dtype=np.float32)
        self._uniforms = np.zeros((n, STEP_DRAWS))

    def _sensor_views(self, sensors: dict[str, slice]) -> None:
        def idx(*names: str) -> np.ndarray:
            return np.concatenate([np.arange(sensors[name].start, sensors[name].stop) for name in names])

        joints = robot.JOINT_NAMES
        self._s_base_pos = idx("base_pos")
        self._s_heading = idx("base_heading")
        self._s_base_up = idx("base_up")
        self._s_linvel = idx("base_linvel")
        self._s_angvel = idx("base_angvel")
        self._s_qpos = idx(*(f"{j}_pos" for j in joints))
        self._s_qvel = idx(*(f"{j}_vel" for j in joints))
        self._s_torque = idx(*(f"{j}_torque" for j in joints))
        self._s_foot_pos = idx("left_foot_pos", "right_foot_pos")
        self._s_foot_up = idx("left_foot_up", "right_foot_up")
        self._s_foot_vel = idx("left_foot_linvel", "right_foot_linvel")
        self._s_foot_force = idx("left_foot_force", "right_foot_force")
        self._s_collision = sensors["leg_collision"].start
        self._hip_roll_yaw = np.array([0, 1, 6, 7])

    # ----------------------------------------------------------------------------------------- reset
    def reset(self, ids: np.ndarray) -> tuple[DomainParams, np.ndarray]:
        """Start new episodes for robots `ids`, drawing from their generators.

        Returns their domain parameters (to apply to their models) and initial generalized positions
        (len(ids), 7 + 12) with the base height left at 0 (the caller places the feet on the ground).
        """
        ids = np.asarray(ids)
        ranges, count = self.ranges, len(ids)
        qpos = np.zeros((count, 7 + robot.NUM_JOINTS))
        rows, command_uniforms = [], np.empty((count, COMMAND_DRAWS))
        for k, i in enumerate(ids):
            rng = self.rngs[i]
            rows.append(sample_domain(rng, ranges))
            joint_scale = rng.uniform(*ranges.init_joint_scale, size=robot.NUM_JOINTS)
            roll, pitch = rng.uniform(-1.0, 1.0, size=2) * ranges.init_roll_pitch
            spawn = rng.uniform(-1.0, 1.0, size=2) * self.terrain.spec.spawn_jitter
            command_uniforms[k] = rng.random(COMMAND_DRAWS)
            self._uniforms[i] = rng.random(STEP_DRAWS)  # the first observation's noise
            qpos[k, :2] = np.asarray(self.terrain.spec.spawn_xy) + spawn
            cr, sr, cp, sp = np.cos(roll / 2), np.sin(roll / 2), np.cos(pitch / 2), np.sin(pitch / 2)
            qpos[k, 3:7] = (cp * cr, cp * sr, sp * cr, -sp * sr)
            qpos[k, 7:] = robot.DEFAULT_JOINT_POS * joint_scale
        domain = DomainParams.stack(rows)
        for name, value in vars(domain).items():
            getattr(self.domain, name)[ids] = value
        self.domain_vector[ids] = domain.as_vector()
        self.lags[ids] = delay_lags(domain.action_delay, robot.PHYSICS_DT, robot.DECIMATION)
        self.command[ids] = (
            self.fixed_command
            if self.fixed_command is not None
            else sample_commands(command_uniforms, self.scenario.command_ranges)
        )
        self.step_count[ids] = 0
        self.phase[ids] = 0.0
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
        for i, rng in enumerate(self.rngs):
            self._uniforms[i] = rng.random(STEP_DRAWS)
        u, step = self._uniforms, self.step_count
        self.force = update_forces(step, u[:, _FORCE], self.force, self.scenario.force)
        if self.fixed_command is None:
            due = (step > 0) & (step % self.command_interval == 0)
            if due.any():
                self.command[due] = sample_commands(u[due, _COMMAND], self.scenario.command_ranges)
        kicks = push_kicks(step, u[:, _PUSH], self.ranges.push_velocity, self.push_interval)
        return targets, self.force, kicks

    def after_physics(self, sensordata: np.ndarray, unstable: np.ndarray) -> StepOutput:
        """Observations, rewards and episode ends from the sensors (n, nsensordata) after the physics steps."""
        self.step_count += 1
        self.phase = (self.phase + self._phase_step) % 1.0
        if unstable.any():
            sensordata = np.where(unstable[:, None], 0.0, sensordata)
        ev = self._evaluate(slice(None), sensordata, with_rewards=True)
        self.joint_vel = ev.qvel
        terms = ev.terms
        reward = terms.sum(axis=1)
        policy, critic = ev.policy, ev.critic
        fall = ((ev.base_height < FALL_HEIGHT) | (ev.up_z < _COS_FALL_TILT)) & ~unstable
        truncated = ((self.step_count >= EPISODE_STEPS) | unstable) & ~fall
        if unstable.any():
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
        """Everything computed from the sensors of robots `sel`; changes no state."""
        n = len(s)
        command, phase, actions = self.command[sel], self.phase[sel], self.actions[sel]
        base_pos, heading, up = s[:, self._s_base_pos], s[:, self._s_heading], s[:, self._s_base_up]
        linvel, angvel = s[:, self._s_linvel], s[:, self._s_angvel]
        qpos, qvel = s[:, self._s_qpos], s[:, self._s_qvel]
        foot_pos = s[:, self._s_foot_pos].reshape(n, 2, 3)
        foot_force = s[:, self._s_foot_force].reshape(n, 2, 3)

        yaw_norm = np.sqrt(heading[:, 0] ** 2 + heading[:, 1] ** 2) + 1e-9
        cos_yaw, sin_yaw = heading[:, 0] / yaw_norm, heading[:, 1] / yaw_norm
        if self.terrain.is_plane:
            base_height = base_pos[:, 2]
            foot_clearance = foot_pos[..., 2]
            height_samples = np.repeat(foot_clearance, len(HEIGHT_SAMPLE_OFFSETS), axis=1)
        else:
            base_height = base_pos[:, 2] - self.terrain.height_at(base_pos[:, :2])
            foot_clearance = foot_pos[..., 2] - self.terrain.height_at(foot_pos[..., :2])
            dx, dy = HEIGHT_SAMPLE_OFFSETS[:, 0], HEIGHT_SAMPLE_OFFSETS[:, 1]
            offsets = np.stack(
                [
                    cos_yaw[:, None] * dx - sin_yaw[:, None] * dy,
                    sin_yaw[:, None] * dx + cos_yaw[:, None] * dy,
                ],
                axis=-1,
            )  # (n, 9, 2), in the world frame
            points = foot_pos[:, :, None, :2] + offsets[:, None]
            height_samples = (foot_pos[:, :, None, 2] - self.terrain.height_at(points)).reshape(n, -1)

        foot_phase = gait.foot_phases(phase)
        stance = gait.desired_contact(foot_phase)
        foot_contact = foot_force[..., 2] > CONTACT_THRESHOLD
        joint_offset = qpos - robot.DEFAULT_JOINT_POS

        terms = None
        if with_rewards:
            rel = foot_pos[..., :2] - base_pos[:, None, :2]
            foot_xy_yaw = np.stack(
                [cos_yaw[:, None] * rel[..., 0] + sin_yaw[:, None] * rel[..., 1],
                 cos_yaw[:, None] * rel[..., 1] - sin_yaw[:, None] * rel[..., 0]],
                axis=-1,
            )  # fmt: skip
            terms = reward_terms(
                command=command,
                base_linvel=linvel,
                base_angvel=angvel,
                base_up=up,
                base_height=base_height,
                target_height=robot.STANDING_HEIGHT,
                joint_vel=qvel,
                joint_acc=(qvel - self.joint_vel[sel]) / robot.CONTROL_DT,
                torques=s[:, self._s_torque],
                outside_limits=((qpos < self.soft_low) | (qpos > self.soft_high)).any(axis=1),
                hip_roll_yaw=joint_offset[:, self._hip_roll_yaw],
                foot_tilt=np.arccos(np.clip(s[:, self._s_foot_up[2::3]], -1.0, 1.0)),
                foot_vel_xy=s[:, self._s_foot_vel].reshape(n, 2, 3)[..., :2],
                foot_force=foot_force,
                foot_contact=foot_contact,
                foot_clearance=foot_clearance,
                foot_xy_yaw_frame=foot_xy_yaw,
                stance=stance,
                swing_target=gait.swing_height_target(foot_phase),
                raibert_target=gait.raibert_targets(foot_phase, command, robot.HIP_WIDTH),
                leg_collision=s[:, self._s_collision] > 0,
                action=actions[:, 0],
                last_action=actions[:, 1],
                last_last_action=actions[:, 2],
            )
            terms *= self.reward_weights

        policy = np.empty((n, POLICY_SIZE))
        policy[:, 0] = np.arctan2(up[:, 1], up[:, 2])
        policy[:, 1] = np.arcsin(np.clip(-up[:, 0], -1.0, 1.0))
        policy[:, _P["base_angular_velocity"]] = angvel
        policy[:, 5] = np.sin(2.0 * np.pi * phase)
        policy[:, 6] = np.cos(2.0 * np.pi * phase)
        policy[:, _P["command"]] = command
        policy[:, _P["joint_position_offset"]] = joint_offset
        policy[:, _P["joint_velocity"]] = qvel
        policy[:, _P["last_action"]] = actions[:, 0]
        critic = np.empty((n, CRITIC_SIZE), dtype=np.float32)
        critic[:, _C["policy_noiseless"]] = policy
        critic[:, _C["base_linear_velocity"]] = linvel
        critic[:, _C["base_height"].start] = base_height
        critic[:, _C["foot_height_samples"]] = height_samples
        critic[:, _C["foot_contact"]] = foot_contact
        critic[:, _C["foot_contact_force"]] = foot_force.reshape(n, 6)
        critic[:, _C["desired_contact"]] = stance
        critic[:, _C["external_force"]] = self.force[sel]
        critic[:, _DOMAIN] = self.domain_vector[sel]
        if self.noise_scale.any():
            policy += (2.0 * self._uniforms[sel, _NOISE] - 1.0) * self.noise_scale
        velocity_error = linvel[:, :2] - command[:, :2]
        return _Evaluation(
            policy=policy.astype(np.float32),
            critic=critic,
            terms=terms,
            qvel=qvel,
            base_height=base_height,
            up_z=up[:, 2],
            lin_vel_error=np.sqrt(velocity_error[:, 0] ** 2 + velocity_error[:, 1] ** 2),
            ang_vel_error=np.abs(angvel[:, 2] - command[:, 2]),
        )

    def episode_terms(self, i: int) -> dict[str, float]:
        """Per-term sums of the weighted rewards over robot i's episode so far."""
        return dict(zip(REWARD_NAMES, self.episode_sums[i].tolist(), strict=True))
