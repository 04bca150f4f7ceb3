"""`ZerithVecEnv`: n Zerith-1 robots in one process, as a Stable-Baselines3 `VecEnv`.

Observations, rewards and randomization are computed with numpy over the whole batch (`ZerithTask`), the
physics of each robot runs in C (`Simulator`), and robot i seeded with `seed + i` follows exactly the
trajectory of a single `Zerith1Env` seeded with `seed + i` (tested). Use it wherever SB3 takes a VecEnv:

    from stable_baselines3 import PPO
    import zerith_gym

    env = zerith_gym.make_vec_env(16, seed=0, obs_mode="policy")
    PPO("MlpPolicy", env, n_steps=64).learn(10_000)

Semantics follow SB3's `DummyVecEnv` over `Monitor`-wrapped single envs: automatic reset with
`info["terminal_observation"]` and `info["TimeLimit.truncated"]`, `info["episode"]` (return, length, time)
as `Monitor` writes it, so SB3's `ep_rew_mean` logging works without a wrapper. Attributes and methods
are those of the batch, shared by all robots.
"""

from __future__ import annotations

import time
from collections.abc import Mapping, Sequence
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium.utils import seeding
from stable_baselines3.common.monitor import Monitor
from stable_baselines3.common.vec_env import VecEnv
from stable_baselines3.common.vec_env.base_vec_env import VecEnvIndices, VecEnvObs, VecEnvStepReturn

from zerith_gym import robot
from zerith_gym.batch import ACTION_SPACE, ZerithBatch, check_actions, observation_space, reset_command
from zerith_gym.scenarios import Scenario
from zerith_gym.task import EPISODE_STEPS


class ZerithVecEnv(VecEnv):
    """`num_envs` Zerith1-v0 robots stepped together; the other arguments are those of `Zerith1Env`.

    `physics_threads`: threads stepping the robots' physics in parallel (MuJoCo releases the GIL in
    `mj_step`); the transitions are the same for any number. More than one pays where cores are free while
    the env steps, e.g. during rollout collection (docs/performance.md).
    Rendering is not supported (use the single env for videos).
    """

    def __init__(
        self,
        num_envs: int,
        scenario: str | Scenario = "train",
        obs_mode: str = "dict",
        command: tuple[float, float, float] | None = None,
        reward_weights: Mapping[str, float] | None = None,
        terrain_seed: int = 0,
        episode_steps: int = EPISODE_STEPS,
        physics_threads: int = 1,
    ) -> None:
        space = observation_space(obs_mode)
        self.robots = ZerithBatch(
            num_envs, scenario, command, reward_weights, terrain_seed, episode_steps, physics_threads
        )
        self.scenario, self.task = self.robots.scenario, self.robots.task
        self.obs_mode = obs_mode
        self.render_mode = None
        super().__init__(num_envs, space, ACTION_SPACE)
        self._action_shape = (num_envs, robot.NUM_JOINTS)
        self._actions = np.zeros(self._action_shape)
        self._returns = np.zeros(num_envs)
        self._lengths = np.zeros(num_envs, dtype=int)
        self._start_time = time.time()

    # ------------------------------------------------------------------------------------ VecEnv API
    def reset(self) -> VecEnvObs:
        """Reset every robot, with the seeds of `seed()` and options of `set_options()` if given."""
        commands = {i: reset_command(options) for i, options in enumerate(self._options) if options}
        for i, seed in enumerate(self._seeds):
            if seed is not None:
                self.task.rngs[i] = seeding.np_random(seed)[0]
        policy, critic = self.robots.reset(np.arange(self.num_envs), commands)
        self.reset_infos = [{"command": row} for row in self.task.command.copy()]
        self._returns[:] = 0.0
        self._lengths[:] = 0
        self._reset_seeds()
        self._reset_options()
        return self._format(policy, critic)

    def step_async(self, actions: np.ndarray) -> None:
        self._actions = check_actions(actions, self._action_shape)

    def step_wait(self) -> VecEnvStepReturn:
        out, force = self.robots.step(self._actions)
        task = self.task
        self._returns += out.reward
        self._lengths += 1
        command, force = task.command.copy(), force.copy()
        fall, unstable = out.fall.tolist(), out.sim_unstable.tolist()
        lin_error, ang_error = out.lin_vel_error.tolist(), out.ang_vel_error.tolist()
        infos: list[dict[str, Any]] = [
            {
                "fall": fall[i],
                "sim_unstable": unstable[i],
                "lin_vel_error": lin_error[i],
                "ang_vel_error": ang_error[i],
                "external_force": force[i],
                "command": command[i],
                "TimeLimit.truncated": False,
            }
            for i in range(self.num_envs)
        ]
        policy, critic = out.policy_obs.copy(), out.critic_obs.copy()
        dones = out.terminated | out.truncated
        ended = np.flatnonzero(dones)
        if len(ended):
            elapsed = round(time.time() - self._start_time, 6)
            for i in ended.tolist():
                info = infos[i]
                info["TimeLimit.truncated"] = bool(out.truncated[i])
                info["terminal_observation"] = self._format(policy[i].copy(), critic[i].copy())
                info["episode_terms"] = task.episode_terms(i)
                info["episode"] = {
                    "r": round(float(self._returns[i]), 6),
                    "l": int(self._lengths[i]),
                    "t": elapsed,
                }
            policy[ended], critic[ended] = self.robots.reset(ended)
            self._returns[ended] = 0.0
            self._lengths[ended] = 0
            for i in ended.tolist():
                self.reset_infos[i] = {"command": task.command[i].copy()}
        return self._format(policy, critic), out.reward.astype(np.float32), dones, infos

    def close(self) -> None:
        """Stop the physics threads, if any (models and data are freed with the object)."""
        self.robots.sim.close()

    def get_images(self) -> Sequence[np.ndarray | None]:
        return [None] * self.num_envs

    def get_attr(self, attr_name: str, indices: VecEnvIndices = None) -> list[Any]:
        """The batch's attribute `attr_name` (shared by all robots), once per index."""
        value = getattr(self, attr_name)
        return [value for _ in self._get_indices(indices)]

    def set_attr(self, attr_name: str, value: Any, indices: VecEnvIndices = None) -> None:
        """Set the batch's attribute `attr_name`; it is shared, so `indices` must cover every robot."""
        if sorted(self._get_indices(indices)) != list(range(self.num_envs)):
            raise ValueError(
                f"ZerithVecEnv attributes are shared by all robots: cannot set {attr_name!r} on some"
            )
        setattr(self, attr_name, value)

    def env_method(
        self, method_name: str, *method_args, indices: VecEnvIndices = None, **method_kwargs
    ) -> list[Any]:
        """Call the batch's method `method_name` once per index."""
        method = getattr(self, method_name)
        return [method(*method_args, **method_kwargs) for _ in self._get_indices(indices)]

    def env_is_wrapped(self, wrapper_class: type[gym.Wrapper], indices: VecEnvIndices = None) -> list[bool]:
        """True for SB3's `Monitor` only: the env writes `Monitor`'s `info["episode"]` itself."""
        return [wrapper_class is Monitor for _ in self._get_indices(indices)]

    # ------------------------------------------------------------------------------------------------
    def _format(self, policy: np.ndarray, critic: np.ndarray) -> VecEnvObs:
        if self.obs_mode == "policy":
            return policy
        return {"policy": policy, "critic": critic}


def make_vec_env(n_envs: int, seed: int | None = None, **env_kwargs: Any) -> ZerithVecEnv:
    """A `ZerithVecEnv` of `n_envs` robots; robot i is seeded with `seed + i` at the first reset.

    `env_kwargs` are those of `Zerith1Env` (scenario, obs_mode, command, reward_weights, terrain_seed,
    episode_steps) and `physics_threads` (see `ZerithVecEnv`).
    """
    env = ZerithVecEnv(n_envs, **env_kwargs)
    if seed is not None:
        env.seed(seed)
    return env
