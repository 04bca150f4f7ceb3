"""The env class every Zerith robot's env is: one robot on the shared step, with Gymnasium's API."""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np

from zerith_gym.core.infos import step_infos
from zerith_gym.core.scenarios import Scenario, resolve_scenario
from zerith_gym.core.spaces import action_space, check_actions, format_observation, observation_space
from zerith_gym.cpu.batch import ZerithBatch
from zerith_gym.options import ZerithOptions, reset_command
from zerith_gym.terrain.levels import LevelRule

_ROBOT = np.array([0])


class ZerithEnv(gym.Env):
    """One robot of the `robot` class attribute walking on commanded velocities (`Zerith1Env` documents the
    options, infos and rendering; each robot's env class its spaces, rewards and episode end).

    The step is `ZerithBatch` of one robot, the batch `ZerithVecEnv` runs: a single env and robot i of a
    vec env seeded alike follow the same trajectory. `policy_mirror` and `action_mirror` are the robot's
    mirror maps (`LocomotionTask.policy_mirror`; None where it has none).
    """

    metadata: dict[str, Any] = {"render_modes": ["human", "rgb_array"]}
    robot: str
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
        task = self.options.task
        self.policy_mirror, self.action_mirror = task.policy_mirror, task.action_mirror
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
        unless the scenario's terrain has tiles (`zerith_gym.terrain.levels`, `TerrainCurriculum`)."""
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
