"""n Zerith-1 robots in one scenario: the task logic and the physics joined, shared by both envs.

`Zerith1Env` (gymnasium, n = 1) and `ZerithVecEnv` (SB3 VecEnv, n robots) are thin interfaces over
`ZerithBatch`, so a batch of n robots runs exactly the code of n single envs. Argument checks that both
envs share live here too.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np
from gymnasium import spaces

from zerith_gym import robot
from zerith_gym.observations import CRITIC_SIZE, POLICY_SIZE
from zerith_gym.rewards import resolve_reward_weights
from zerith_gym.scenarios import Scenario, get_scenario
from zerith_gym.simulator import Simulator
from zerith_gym.task import EPISODE_STEPS, StepOutput, ZerithTask
from zerith_gym.terrain import Terrain

OBS_MODES = ("dict", "policy")
RESET_OPTIONS = ("command",)


def check_command(command: Any, where: str) -> np.ndarray:
    """`command` as a (3,) float array; ValueError naming `where` unless it is three finite numbers."""
    value = np.asarray(command, dtype=float)
    if value.shape != (3,) or not np.isfinite(value).all():
        raise ValueError(
            f"{where} must be three finite numbers (vx m/s, vy m/s, yaw rate rad/s), got {command!r}"
        )
    return value


def reset_command(options: Mapping[str, Any] | None) -> np.ndarray | None:
    """The episode's command from reset `options` (None if not given); ValueError on unknown options."""
    options = dict(options or {})
    unknown = set(options) - set(RESET_OPTIONS)
    if unknown:
        valid = ", ".join(RESET_OPTIONS)
        raise ValueError(f"unknown reset option(s) {sorted(unknown)}; valid options: {valid}")
    if "command" not in options:
        return None
    return check_command(options["command"], "options['command']")


def observation_space(obs_mode: str) -> spaces.Space:
    """The observation space of one robot for `obs_mode`; ValueError listing the valid modes."""
    if obs_mode not in OBS_MODES:
        raise ValueError(f"unknown obs_mode {obs_mode!r}; valid values: {', '.join(OBS_MODES)}")
    policy = spaces.Box(-np.inf, np.inf, shape=(POLICY_SIZE,), dtype=np.float32)
    if obs_mode == "policy":
        return policy
    critic = spaces.Box(-np.inf, np.inf, shape=(CRITIC_SIZE,), dtype=np.float32)
    return spaces.Dict({"policy": policy, "critic": critic})


ACTION_SPACE = spaces.Box(-1.0, 1.0, shape=(robot.NUM_JOINTS,), dtype=np.float32)


def check_actions(actions: Any, shape: tuple[int, ...]) -> np.ndarray:
    """Actions as float64 of `shape`, clipped to [-1, 1]; ValueError on a wrong shape or non-finite values."""
    actions = np.array(actions, dtype=np.float64)
    if actions.shape != shape:
        raise ValueError(f"action must have shape {shape}, got {actions.shape}")
    if not np.isfinite(actions).all():
        raise ValueError(f"action contains NaN or infinite values: {actions}")
    return np.minimum(
        np.maximum(actions, -1.0, out=actions), 1.0, out=actions
    )  # np.clip, without its overhead


class ZerithBatch:
    """`num_robots` robots: their simulations (`sim`) and task state (`task`), reset and stepped together."""

    def __init__(
        self,
        num_robots: int,
        scenario: str | Scenario = "train",
        command: tuple[float, float, float] | None = None,
        reward_weights: Mapping[str, float] | None = None,
        terrain_seed: int = 0,
        episode_steps: int = EPISODE_STEPS,
        physics_threads: int = 1,
    ) -> None:
        if not isinstance(num_robots, int | np.integer) or num_robots < 1:
            raise ValueError(f"the number of robots must be a positive integer, got {num_robots!r}")
        if not isinstance(episode_steps, int | np.integer) or episode_steps < 1:
            raise ValueError(f"episode_steps must be a positive integer, got {episode_steps!r}")
        self.scenario = scenario if isinstance(scenario, Scenario) else get_scenario(scenario)
        if command is not None:
            command = tuple(check_command(command, "command").tolist())
        elif self.scenario.command is not None:
            command = self.scenario.command
        self.terrain = Terrain(self.scenario.terrain, seed=terrain_seed)
        self.sim = Simulator(num_robots, self.terrain, self.scenario.force.target, physics_threads)
        model = self.sim.models[0]
        self.task = ZerithTask(
            num_robots,
            self.scenario,
            self.terrain,
            robot.sensor_slices(model),
            np.array([model.joint(name).range for name in robot.JOINT_NAMES]),
            resolve_reward_weights(reward_weights),
            command,
            int(episode_steps),
        )

    def reset(
        self, ids: np.ndarray, commands: Mapping[int, np.ndarray] | None = None
    ) -> tuple[np.ndarray, np.ndarray]:
        """Start new episodes of robots `ids`; `commands` fixes some robots' commands for the episode.

        Returns their policy and critic observations.
        """
        domain, qpos = self.task.reset(ids)
        for i, command in (commands or {}).items():
            self.task.set_command(np.array([i]), command)
        self.sim.reset(ids, domain, qpos, self.task.lags[ids])
        return self.task.observe(ids, self.sim.sensordata[ids])

    def step(self, actions: np.ndarray) -> tuple[StepOutput, np.ndarray]:
        """One control step of every robot with checked actions (n, 12): outputs and external forces."""
        targets, force, kicks = self.task.before_physics(actions)
        unstable = self.sim.step(targets, force, kicks)
        return self.task.after_physics(self.sim.sensordata, unstable), force
