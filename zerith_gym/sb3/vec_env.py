"""`ZerithVecEnv`: n Zerith-1 robots stepped together, as a Stable-Baselines3 `VecEnv`.

Observations, rewards and randomization are computed with numpy over batches of robots (`ZerithTask`),
the physics of each robot runs in C (`Simulator`); the robots are split into slices, one per core by
default, stepped in parallel by this process and worker processes (`zerith_gym.cpu.workers`). Robot i seeded
with `seed + i` follows exactly the trajectory of a single `Zerith1Env` seeded with `seed + i`, whatever
the number of workers (tested). Use it wherever SB3 takes a VecEnv:

    from stable_baselines3 import PPO
    import zerith_gym

    env = zerith_gym.make_vec_env(16, seed=0, obs_mode="policy")
    PPO("MlpPolicy", env, n_steps=64).learn(10_000)

Semantics follow SB3's `DummyVecEnv` over `Monitor`-wrapped single envs: automatic reset with
`info["terminal_observation"]` and `info["TimeLimit.truncated"]`, `info["episode"]` (return, length, time)
as `Monitor` writes it, so SB3's `ep_rew_mean` logging works without a wrapper; `info["reward_terms"]`
every step and `info["episode_terms"]` at episode ends. Attributes and methods are those of the VecEnv,
shared by all robots. Reset options (SB3's `set_options`, per robot or for all) are the single env's:
`{"command": (vx, vy, yaw rate)}` fixes a robot's command for the episode, and on a tile terrain
`{"tile": (level, kind column)}` starts it on that tile (a resumed terrain curriculum places its robots
with it).
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium.utils import seeding
from stable_baselines3.common.monitor import Monitor
from stable_baselines3.common.vec_env import VecEnv
from stable_baselines3.common.vec_env.base_vec_env import VecEnvIndices, VecEnvObs, VecEnvStepReturn

from zerith_gym.core.contract import Robots, check_num_robots
from zerith_gym.core.infos import step_infos
from zerith_gym.core.scenarios import Scenario, resolve_scenario
from zerith_gym.core.spaces import action_space, check_actions, format_observation, observation_space
from zerith_gym.cpu.batch import ZerithBatch
from zerith_gym.cpu.workers import WorkerPool, default_workers
from zerith_gym.options import ZerithOptions, reset_command
from zerith_gym.terrain.levels import LevelRule, check_tile

SIMULATION_BACKENDS = ("cpu", "mjx")
"""Where the robots are simulated: "cpu" (MuJoCo, one model per robot, worker processes) or "mjx"
(MuJoCo MJX on JAX's default device, a GPU where there is one: `pip install "sb3-huri[mjx]"`)."""


class ZerithVecEnv(VecEnv):
    """`num_envs` Zerith1-v0 robots stepped together; `options` are those of `ZerithOptions`.

    `workers`: worker processes stepping slices of the robots (each with its own task logic and physics,
    `zerith_gym.cpu.workers`) while this process steps the first slice; 0 steps every robot in this process.
    The default (None) makes one slice per CPU core with at least 8 robots each, so `cores - 1` workers,
    or 0 where that gives one slice (`default_workers`). `physics_threads`: threads stepping the physics
    of the robots of one process (MuJoCo releases the GIL in `mj_step`; the task logic stays on one).
    The transitions are the same for any number of workers and threads (tested).

    `backend="mjx"` simulates the robots with MuJoCo MJX on JAX's default device (`zerith_gym.mjx`,
    docs/gpu.md): the same task code, one jitted step for all robots; `solver_iterations` and
    `ls_iterations` override the MJCF's constraint solver iterations (100 / 50) there. Its randomness
    comes from one JAX key seeded by `seed`, so its episodes differ from the CPU backend's draws.
    Rendering is not supported (use the single env for videos). `policy_mirror` and `action_mirror` are
    the robot's mirror maps (`LocomotionTask.policy_mirror`; None where it has none), as the single env's.
    """

    def __init__(
        self,
        num_envs: int,
        *,
        backend: str = "cpu",
        workers: int | None = None,
        physics_threads: int = 1,
        solver_iterations: int | None = None,
        ls_iterations: int | None = None,
        **options: Any,
    ) -> None:
        self.options = ZerithOptions.from_kwargs(options, "ZerithVecEnv")
        check_num_robots(num_envs)
        if backend not in SIMULATION_BACKENDS:
            raise ValueError(f"unknown backend {backend!r}; valid backends: {', '.join(SIMULATION_BACKENDS)}")
        self.backend = backend
        self.robots: Robots
        if backend == "mjx":
            if workers or physics_threads != 1:
                raise ValueError("workers and physics_threads are options of the cpu backend, not of mjx")
            from zerith_gym.mjx import MjxBatch, SolverSettings

            self.workers = 0
            self.robots = MjxBatch(num_envs, self.options, SolverSettings(solver_iterations, ls_iterations))
        elif solver_iterations is not None or ls_iterations is not None:
            raise ValueError("solver_iterations and ls_iterations are options of the mjx backend")
        else:
            self.workers = default_workers(num_envs) if workers is None else workers
            if self.workers:
                self.robots = WorkerPool(num_envs, self.options, self.workers, physics_threads)
            else:
                self.robots = ZerithBatch(num_envs, self.options, physics_threads)
        self.scenario = self.options.resolved_scenario
        self.obs_mode = self.options.obs_mode
        self.render_mode = None
        self.reward_names = self.options.task.reward_names
        task = self.options.task
        self.policy_mirror, self.action_mirror = task.policy_mirror, task.action_mirror
        robot_actions = action_space(self.options.task.robot)
        super().__init__(num_envs, observation_space(self.obs_mode, self.options.task), robot_actions)
        self._action_shape = (num_envs, *robot_actions.shape)
        self._action_clip = self.options.task.robot.action_clip
        self._actions = np.zeros(self._action_shape)
        self._returns = np.zeros(num_envs)
        self._lengths = np.zeros(num_envs, dtype=int)
        self._term_sums = np.zeros((num_envs, len(self.reward_names)))
        self._start_time = time.time()
        self._reset_done = False
        self.terrain_levels = np.zeros(num_envs, dtype=int)
        """The terrain level (tile row) each robot walked on in the last step (0 off tile terrains)."""

    # ------------------------------------------------------------------------------------ VecEnv API
    def reset(self) -> VecEnvObs:
        """Reset every robot, with the seeds of `seed()` and options of `set_options()` if given."""
        commands, tiles = {}, {}
        for i, options in enumerate(self._options):
            command = reset_command(options, also_valid=("tile",))
            if command is not None:
                commands[i] = command
            if options and "tile" in options:
                tiles[i] = check_tile(self.scenario.terrain, options["tile"])
        seeds = {i: seeding.np_random(seed)[0] for i, seed in enumerate(self._seeds) if seed is not None}
        self.robots.seed(seeds)
        policy, critic = self.robots.reset(np.arange(self.num_envs), commands, tiles)
        self.reset_infos = [{"command": row} for row in self.robots.commands.copy()]
        self._returns[:] = 0.0
        self._lengths[:] = 0
        self._term_sums[:] = 0.0
        self._reset_seeds()
        self._reset_options()
        self._reset_done = True
        return format_observation(self.obs_mode, policy, critic)

    def step_async(self, actions: np.ndarray) -> None:
        if not self._reset_done:
            raise RuntimeError(
                "ZerithVecEnv: call reset() before the first step (the robots are not placed yet)"
            )
        self._actions = check_actions(actions, self._action_shape, self._action_clip)

    def step_wait(self) -> VecEnvStepReturn:
        step = self.robots.step(self._actions)
        self.terrain_levels = step.terrain_level
        out = step.out
        self._returns += out.reward
        self._lengths += 1
        self._term_sums += out.terms
        infos = step_infos(step)  # read lazily from the step's arrays (zerith_gym.core.infos)
        dones = out.terminated | out.truncated
        ended = np.flatnonzero(dones).tolist()
        if ended:
            elapsed = round(time.time() - self._start_time, 6)
            for i in ended:
                info = infos[i]
                info["TimeLimit.truncated"] = bool(out.truncated[i])
                info["terminal_observation"] = format_observation(
                    self.obs_mode, out.policy_obs[i], out.critic_obs[i]
                )
                info["episode_terms"] = dict(zip(self.reward_names, self._term_sums[i].tolist(), strict=True))
                info["episode"] = {
                    "r": round(float(self._returns[i]), 6),
                    "l": int(self._lengths[i]),
                    "t": elapsed,
                }
                self.reset_infos[i] = {"command": step.next_command[i].copy()}
            self._returns[ended] = 0.0
            self._lengths[ended] = 0
            self._term_sums[ended] = 0.0
        # The step's arrays are never written again (`ZerithTask.observe`): SB3 may keep them as they are.
        observation = format_observation(self.obs_mode, step.policy_obs, step.critic_obs)
        return observation, out.reward.astype(np.float32), dones, infos

    def set_scenario(self, scenario: str | Scenario) -> None:
        """Follow another scenario from now on, e.g. a curriculum's next stage (`scenarios.scaled_scenario`).

        Its randomization ranges apply from each robot's next reset; forces, pushes, observation noise
        and command draws from the next step. The terrain cannot change (ValueError).
        """
        scenario = resolve_scenario(scenario)
        self.robots.set_scenario(scenario)
        self.scenario = scenario

    def set_level_rule(self, rule: LevelRule | None) -> None:
        """Move robots between terrain levels by `rule` when their episodes end (None: stop); ValueError
        unless the scenario's terrain has tiles (`zerith_gym.terrain.levels`, `TerrainCurriculum`)."""
        self.robots.set_level_rule(rule)

    def close(self) -> None:
        """Stop the worker processes or physics threads, if any (models and data go with the object)."""
        self.robots.close()

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


def make_vec_env(n_envs: int, seed: int | None = None, **env_kwargs: Any) -> ZerithVecEnv:
    """A `ZerithVecEnv` of `n_envs` robots; robot i is seeded with `seed + i` at the first reset.

    `env_kwargs` are the options of `ZerithOptions` (scenario, obs_mode, command, reward_weights,
    terrain_seed, episode_steps, robot: "go2like" for the quadruped), `backend` ("cpu" or "mjx"), and
    the backend's own: `workers`, `physics_threads` (cpu), `solver_iterations`, `ls_iterations`
    (mjx); see `ZerithVecEnv`.
    """
    env = ZerithVecEnv(n_envs, **env_kwargs)
    if seed is not None:
        env.seed(seed)
    return env
