"""Zerith1-v0: a 12-DoF Zerith-1-like humanoid learning to walk under disturbances (MuJoCo)."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import gymnasium as gym
import mujoco
import numpy as np
from gymnasium import spaces

from zerith_gym import robot
from zerith_gym.disturbances import FORCE_TARGETS
from zerith_gym.observations import CRITIC_SIZE, POLICY_SIZE
from zerith_gym.physics import (
    NominalModel,
    apply_domain,
    build_model,
    reset_state,
    state_is_bad,
    warning_count,
)
from zerith_gym.rewards import resolve_reward_weights
from zerith_gym.scenarios import SCENARIOS, Scenario, get_scenario
from zerith_gym.task import ZerithTask
from zerith_gym.terrain import Terrain

OBS_MODES = ("dict", "policy")
RESET_OPTIONS = ("command",)


def _check_command(command: Any, where: str) -> np.ndarray:
    value = np.asarray(command, dtype=float)
    if value.shape != (3,) or not np.isfinite(value).all():
        raise ValueError(
            f"{where} must be three finite numbers (vx m/s, vy m/s, yaw rate rad/s), got {command!r}"
        )
    return value


class Zerith1Env(gym.Env):
    """Zerith-1 humanoid walking on commanded velocities, with the HuRi paper's randomization and tests.

    ## Action space
    `Box(-1, 1, (12,))`: joint-position offsets from the default stance, scaled per joint by
    `robot.ACTION_SCALE` (rad), in the order of `robot.JOINT_NAMES` (left leg then right leg: hip_yaw,
    hip_roll, hip_pitch, knee, ankle_pitch, ankle_roll). Position actuators (PD with torque limits) track
    the targets at the physics rate; the policy runs at 50 Hz. Out-of-range actions are clipped; NaN or
    infinite ones raise `ValueError`.

    ## Observation space
    `obs_mode="dict"` (default): `Dict(policy=Box(46), critic=Box(139))`; `obs_mode="policy"`: the 46-d
    policy Box alone. Policy: base roll and pitch, base angular velocity, clock sin/cos, command, joint
    positions relative to the default stance, joint velocities, last action (noisy in training). Critic:
    the noiseless policy terms, base linear velocity and height, ground height around each foot, foot
    contacts and forces, the gait's desired contacts, the external force and the domain parameters.
    Layouts: `zerith_gym.observations`; index tables in docs/zerith1.md.

    ## Rewards
    The terms of the paper's Table 4 (`zerith_gym.rewards.DEFAULT_REWARD_WEIGHTS`), each weighted and
    multiplied by the control period (0.02 s). Override weights with `reward_weights={name: weight}`.
    `info["episode_terms"]` holds each term's episode sum when an episode ends.

    ## Episode end
    Terminated on a fall: pelvis below 0.45 m above the ground or tilted more than 0.8 rad. Truncated at
    20 s (1000 steps), and when the simulation diverges (`info["sim_unstable"]`; the last finite
    observation is returned with reward 0).

    ## Arguments
    - `scenario`: a name in `zerith_gym.SCENARIOS` (default "train"), or a custom `Scenario`.
    - `obs_mode`: "dict" or "policy".
    - `command`: fixed (vx, vy, yaw rate); default: drawn during the episode (train, nominal) or
      (1, 0, 0) in the evaluation scenarios. `reset(options={"command": ...})` sets it for one episode.
    - `reward_weights`: overrides of the reward weights.
    - `render_mode`: "human" or "rgb_array" (camera following the robot); `width`, `height`.
    - `terrain_seed`: seed of the uneven terrain's heights (fixed for the env's lifetime).

    ## Info (every step)
    `fall`, `sim_unstable`, `lin_vel_error` (|v_xy - v_cmd|), `ang_vel_error` (|yaw rate - cmd|),
    `external_force` (N, world frame, on each body of the scenario's target group), `command`.
    """

    metadata = {"render_modes": ["human", "rgb_array"], "render_fps": round(1.0 / robot.CONTROL_DT)}

    def __init__(
        self,
        scenario: str | Scenario = "train",
        obs_mode: str = "dict",
        command: tuple[float, float, float] | None = None,
        reward_weights: Mapping[str, float] | None = None,
        render_mode: str | None = None,
        width: int = 640,
        height: int = 480,
        terrain_seed: int = 0,
    ) -> None:
        self.scenario = scenario if isinstance(scenario, Scenario) else get_scenario(scenario)
        if obs_mode not in OBS_MODES:
            raise ValueError(f"unknown obs_mode {obs_mode!r}; valid values: {', '.join(OBS_MODES)}")
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            modes = ", ".join(self.metadata["render_modes"])
            raise ValueError(f"unknown render_mode {render_mode!r}; valid values: None, {modes}")
        if command is not None:
            command = tuple(_check_command(command, "command"))
        elif self.scenario.command is not None:
            command = self.scenario.command
        self.obs_mode = obs_mode
        self.render_mode = render_mode

        self.terrain = Terrain(self.scenario.terrain, seed=terrain_seed)
        self.model = build_model(self.terrain)
        self.data = mujoco.MjData(self.model)
        self.nominal = NominalModel.capture(self.model, self.terrain)
        sensors = robot.sensor_slices(self.model)
        joint_range = np.array([self.model.joint(name).range for name in robot.JOINT_NAMES])
        self.task = ZerithTask(
            1,
            self.scenario,
            self.terrain,
            sensors,
            joint_range,
            resolve_reward_weights(reward_weights),
            command,
        )
        self._force_bodies = np.array(
            [self.model.body(b).id for b in FORCE_TARGETS[self.scenario.force.target]]
        )
        self._segments: list[tuple[int, int]] = [(0, robot.DECIMATION)]
        self._needs_reset = True

        self.action_space = spaces.Box(-1.0, 1.0, shape=(robot.NUM_JOINTS,), dtype=np.float32)
        policy_space = spaces.Box(-np.inf, np.inf, shape=(POLICY_SIZE,), dtype=np.float32)
        if obs_mode == "policy":
            self.observation_space = policy_space
        else:
            critic_space = spaces.Box(-np.inf, np.inf, shape=(CRITIC_SIZE,), dtype=np.float32)
            self.observation_space = spaces.Dict({"policy": policy_space, "critic": critic_space})

        self.width, self.height = width, height
        self._renderer = None

    # ------------------------------------------------------------------------------------------------
    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        super().reset(seed=seed)
        options = dict(options or {})
        unknown = set(options) - set(RESET_OPTIONS)
        if unknown:
            raise ValueError(
                f"unknown reset option(s) {sorted(unknown)}; valid options: {', '.join(RESET_OPTIONS)}"
            )
        task = self.task
        task.rngs[0] = self.np_random
        domain, qpos = task.reset(np.array([0]))
        if "command" in options:
            task.set_command(np.array([0]), _check_command(options["command"], "options['command']"))
        apply_domain(self.model, self.nominal, domain)
        reset_state(self.model, self.data, qpos[0], self.terrain, self.nominal.foot_geoms)
        lags = task.lags[0].tolist()
        self._segments = [(lag, lags.count(lag)) for lag in sorted(set(lags), reverse=True)]
        policy, critic = task.observe(np.array([0]), self.data.sensordata[None])
        self._needs_reset = False
        info = {"command": task.command[0].copy()}
        return self._format(policy[0], critic[0]), info

    def step(self, action):
        if self._needs_reset:
            raise RuntimeError("Zerith1Env.step() called before reset() or after the episode ended")
        action = np.asarray(action, dtype=np.float64)
        if action.shape != (robot.NUM_JOINTS,):
            raise ValueError(f"action must have shape ({robot.NUM_JOINTS},), got {action.shape}")
        if not np.isfinite(action).all():
            raise ValueError(f"action contains NaN or infinite values: {action}")
        np.clip(action, -1.0, 1.0, out=action)

        model, data, task = self.model, self.data, self.task
        targets, force, kicks = task.before_physics(action[None])
        data.xfrc_applied[self._force_bodies, :3] = force[0]
        if kicks is not None:
            data.qvel[:2] += kicks[0]
        warnings = warning_count(data)
        for lag, count in self._segments:
            data.ctrl[:] = targets[0, lag]
            mujoco.mj_step(model, data, nstep=count)
        unstable = state_is_bad(data, warnings)
        out = task.after_physics(data.sensordata[None], np.array([unstable]))

        terminated, truncated = bool(out.terminated[0]), bool(out.truncated[0])
        info = {
            "fall": bool(out.fall[0]),
            "sim_unstable": unstable,
            "lin_vel_error": float(out.lin_vel_error[0]),
            "ang_vel_error": float(out.ang_vel_error[0]),
            "external_force": force[0].copy(),
            "command": task.command[0].copy(),
        }
        if terminated or truncated:
            info["episode_terms"] = task.episode_terms(0)
            self._needs_reset = True
        if self.render_mode == "human":
            self.render()
        return (
            self._format(out.policy_obs[0], out.critic_obs[0]),
            float(out.reward[0]),
            terminated,
            truncated,
            info,
        )

    def _format(self, policy: np.ndarray, critic: np.ndarray):
        if self.obs_mode == "policy":
            return policy
        return {"policy": policy, "critic": critic}

    # ------------------------------------------------------------------------------------------------
    def render(self):
        if self.render_mode is None:
            gym.logger.warn("render() called without a render_mode; pass render_mode='rgb_array' or 'human'")
            return None
        if self._renderer is None:
            from gymnasium.envs.mujoco.mujoco_rendering import MujocoRenderer

            camera = {
                "type": mujoco.mjtCamera.mjCAMERA_TRACKING,
                "trackbodyid": self.nominal.root,
                "distance": 3.0,
                "elevation": -15.0,
                "azimuth": 150.0,
            }
            self._renderer = MujocoRenderer(self.model, self.data, camera, self.width, self.height)
        return self._renderer.render(self.render_mode)

    def close(self) -> None:
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None


__all__ = ["SCENARIOS", "Zerith1Env"]
