"""Zerith1-v0: a 12-DoF Zerith-1-like humanoid learning to walk under disturbances (MuJoCo)."""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np

from zerith_gym import robot
from zerith_gym.cpu.batch import ZerithBatch
from zerith_gym.infos import step_infos
from zerith_gym.options import ZerithOptions, reset_command
from zerith_gym.scenarios import SCENARIOS, Scenario, resolve_scenario
from zerith_gym.spaces import action_space, check_actions, format_observation, observation_space
from zerith_gym.symmetry import ACTION_MIRROR, POLICY_MIRROR
from zerith_gym.terrain_levels import LevelRule

_ROBOT = np.array([0])


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
    Each term is a named function in `zerith_gym.rewards` (`TERMS`). `info["reward_terms"]` holds each
    term's weighted value of the step (they sum to the reward), `info["episode_terms"]` each term's
    episode sum when an episode ends.

    ## Episode end
    Terminated on a fall: pelvis below 0.45 m above the ground or tilted more than 0.8 rad. Truncated at
    20 s (1000 steps), and when the simulation diverges (`info["sim_unstable"]`; the last finite
    observation is returned with reward 0).

    ## Arguments
    The task options (declared once, in `zerith_gym.options.ZerithOptions`, for every Zerith env):
    - `scenario`: a name in `zerith_gym.SCENARIOS` (default "train"), or a custom `Scenario`.
    - `obs_mode`: "dict" or "policy".
    - `command`: fixed (vx, vy, yaw rate); default: drawn during the episode (train, nominal) or
      (1, 0, 0) in the evaluation scenarios. `reset(options={"command": ...})` sets it for one episode.
      On a tile terrain, `reset(options={"tile": (level, kind column)})` starts the robot on that tile
      (default: level 0 of the first kind; a `TerrainCurriculum` moves it on from there).
    - `reward_weights`: overrides of the reward weights.
    - `terrain_seed`: seed of the height field's heights, uneven or tiles (fixed for the env's lifetime).
    - `episode_steps`: control steps before the time-out truncation (default 1000, 20 s). The env
      truncates itself (and reports `episode_terms`); beyond 1000 also raise `gym.make`'s
      `max_episode_steps`.

    and, for this env only, `render_mode`: "human" or "rgb_array" (camera following the robot);
    `width`, `height`.

    ## Info (every step)
    `fall`, `sim_unstable`, `lin_vel_error` (|v_xy - v_cmd|), `ang_vel_error` (|yaw rate - cmd|),
    `external_force` (N, world frame, on each body of the scenario's target group: its first body's where
    each body draws its own force, `ForceSchedule.per_body`), `command`,
    `reward_terms` (name -> weighted value), `terrain_level` (the tile row walked on: 0 unless the
    scenario's terrain has tiles); at an episode's end also `episode_terms`.

    ## Symmetry
    `policy_mirror` and `action_mirror` reflect the actor's observation and an action left to right
    (`zerith_gym.symmetry`), for a symmetry loss (`HuRiPPO(mirror_coef=...)`).
    """

    metadata = {"render_modes": ["human", "rgb_array"], "render_fps": round(1.0 / robot.CONTROL_DT)}
    policy_mirror = POLICY_MIRROR
    action_mirror = ACTION_MIRROR
    robot = "zerith1"
    """The robot this env simulates (its `robot` option may only repeat it)."""

    def __init__(
        self, render_mode: str | None = None, width: int = 640, height: int = 480, **options: Any
    ) -> None:
        if options.setdefault("robot", self.robot) != self.robot:
            raise ValueError(
                f"{type(self).__name__} simulates the {self.robot} robot, got robot={options['robot']!r}; "
                "make Zerith1-v0 or Go2Like-v0 for the robot you want"
            )
        self.options = ZerithOptions.from_kwargs(options)
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            modes = ", ".join(self.metadata["render_modes"])
            raise ValueError(f"unknown render_mode {render_mode!r}; valid values: None, {modes}")
        self.reward_names = self.options.task.reward_names
        self.observation_space = observation_space(self.options.obs_mode, self.options.task)
        self.action_space = action_space(self.options.task.robot)
        self.obs_mode = self.options.obs_mode
        self.render_mode = render_mode
        self.robots = ZerithBatch(1, self.options)
        self.scenario, self.terrain, self.task = self.robots.scenario, self.robots.terrain, self.robots.task
        sim = self.robots.sim
        self.model, self.data, self.nominal = sim.models[0], sim.datas[0], sim.nominal
        self._needs_reset = True
        self._episode_terms = np.zeros(len(self.reward_names))
        self.width, self.height = width, height
        self._renderer = None

    # ------------------------------------------------------------------------------------------------
    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        super().reset(seed=seed)
        command = reset_command(options, also_valid=("tile",))
        tile = (options or {}).get("tile")
        self.robots.seed({0: self.np_random})
        policy, critic = self.robots.reset(
            _ROBOT, None if command is None else {0: command}, None if tile is None else {0: tile}
        )
        self._needs_reset = False
        self._episode_terms[:] = 0.0
        observation = format_observation(self.obs_mode, policy[0], critic[0])
        return observation, {"command": self.robots.commands[0].copy()}

    def step(self, action):
        if self._needs_reset:
            raise RuntimeError(
                f"{type(self).__name__}.step() called before reset() or after the episode ended"
            )
        actions = check_actions(action, self.action_space.shape, self.options.task.robot.action_clip)
        step = self.robots.step(actions[None], autoreset=False)
        out = step.out
        self._episode_terms += out.terms[0]
        terminated, truncated = bool(out.terminated[0]), bool(out.truncated[0])
        info = dict(step_infos(step)[0])
        if terminated or truncated:
            info["episode_terms"] = dict(zip(self.reward_names, self._episode_terms.tolist(), strict=True))
            self._needs_reset = True
        if self.render_mode == "human":
            self.render()
        observation = format_observation(self.obs_mode, out.policy_obs[0], out.critic_obs[0])
        return observation, float(out.reward[0]), terminated, truncated, info

    def set_scenario(self, scenario: str | Scenario) -> None:
        """Follow another scenario from now on (see `ZerithVecEnv.set_scenario`)."""
        scenario = resolve_scenario(scenario)
        self.robots.set_scenario(scenario)
        self.scenario = scenario

    def set_level_rule(self, rule: LevelRule | None) -> None:
        """Move the robot between terrain levels by `rule` when its episodes end (None: stop); ValueError
        unless the scenario's terrain has tiles (`zerith_gym.terrain_levels`, `TerrainCurriculum`)."""
        self.robots.set_level_rule(rule)

    # ------------------------------------------------------------------------------------------------
    def render(self):
        if self.render_mode is None:
            gym.logger.warn("render() called without a render_mode; pass render_mode='rgb_array' or 'human'")
            return None
        if self._renderer is None:
            from gymnasium.envs.mujoco.mujoco_rendering import MujocoRenderer

            # The model's "track" camera follows the centre of mass (gymnasium's free camera would not).
            self._renderer = MujocoRenderer(
                self.model, self.data, None, self.width, self.height, camera_name="track"
            )
        return self._renderer.render(self.render_mode)

    def close(self) -> None:
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None


__all__ = ["SCENARIOS", "Zerith1Env"]
