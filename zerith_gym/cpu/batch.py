"""n Zerith-1 robots in one scenario in this process: the task logic joined with the physics.

`Zerith1Env` (gymnasium, n = 1), `ZerithVecEnv` (SB3 VecEnv, n robots) and each worker process of a
`ZerithVecEnv` are thin interfaces over `ZerithBatch`, so a batch of n robots runs exactly the code of n
single envs. Their options are in `zerith_gym.options`, the spaces and per-step infos in `zerith_gym.core`.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from zerith_gym.core.contract import BatchStep, check_num_robots, check_scenario_change
from zerith_gym.core.scenarios import Scenario
from zerith_gym.core.task import ZerithTask, task_constants
from zerith_gym.cpu.simulator import Simulator
from zerith_gym.options import ZerithOptions, resolve_reward_weights
from zerith_gym.terrain.ground import Terrain
from zerith_gym.terrain.levels import LevelRule


class ZerithBatch:
    """`num_robots` robots: their simulations (`sim`) and task state (`task`), reset and stepped together in
    this process (the robots contract, `zerith_gym.core.contract.Robots`; `step` may also leave ended episodes
    for the caller to reset, as the single env does). `first_robot`: the env-wide index of the first of
    them (a worker's slice starts later), which sets their tiles on a tile terrain."""

    def __init__(
        self, num_robots: int, options: ZerithOptions, physics_threads: int = 1, first_robot: int = 0
    ) -> None:
        self.num_robots = check_num_robots(num_robots)
        self.options = options
        self.scenario = options.resolved_scenario
        self.terrain = Terrain(self.scenario.terrain, seed=options.terrain_seed)
        task = options.task
        self.sim = Simulator(num_robots, self.terrain, task.robot, physics_threads)
        model = self.sim.models[0]
        self.task = ZerithTask(
            num_robots,
            self.scenario,
            task.robot.sensor_layout(model),
            task_constants(
                self.terrain,
                np.array([model.joint(name).range for name in task.robot.joint_names]),
                resolve_reward_weights(options.reward_weights, task.reward_weights),
                int(options.episode_steps),
                task,
            ),
            options.fixed_command(self.scenario),
            first_robot,
        )

    def set_scenario(self, scenario: Scenario) -> None:
        """Follow `scenario` from now on (see `ZerithTask.set_scenario`); its terrain and force target
        must be those of the current one, which the models were built for."""
        check_scenario_change(self.scenario, scenario)
        for target in scenario.force.targets:
            self.options.task.robot.force_target_bodies(target)
        self.scenario = scenario
        self.task.set_scenario(scenario, self.options.fixed_command(scenario))

    def set_level_rule(self, rule: LevelRule | None) -> None:
        """Move robots between terrain levels by `rule` as episodes end (`zerith_gym.terrain.levels`)."""
        self.task.set_level_rule(rule)

    def seed(self, seeds: Mapping[int, np.random.Generator]) -> None:
        """Give robots their random generators for the next resets and steps (robot index -> generator)."""
        for i, rng in seeds.items():
            self.task.rngs[i] = rng

    def reset(
        self,
        ids: np.ndarray,
        commands: Mapping[int, np.ndarray] | None = None,
        tiles: Mapping[int, tuple[int, int]] | None = None,
    ) -> tuple[np.ndarray, np.ndarray]:
        """Start new episodes of robots `ids`; `commands` fixes some robots' commands for the episode, `tiles`
        the (level, kind column) some start on (`TerrainLevels.place`; a curriculum moves them on from there).

        Returns their policy and critic observations.
        """
        for i, tile in (tiles or {}).items():
            self.task.tiles.place(i, tile)
        domain, qpos = self.task.reset(ids)
        for i, command in (commands or {}).items():
            self.task.set_command(np.array([i]), command)
        self.sim.reset(ids, domain, qpos, self.task.state.lags[ids])
        return self.task.observe(ids, self.sim.sensordata[ids])

    @property
    def commands(self) -> np.ndarray:
        """The current command of every robot, (n, 3) (a live array: copy what you keep)."""
        return self.task.state.command

    def step(self, actions: np.ndarray, autoreset: bool = True) -> BatchStep:
        """One control step of every robot with checked actions (n, 12).

        With `autoreset`, robots whose episode ended start a new one, and the returned next observations
        and commands are the new episode's.
        """
        level = self.task.tiles.levels.copy()
        targets, drawn = self.task.before_physics(actions)
        force, command = drawn.force.copy(), self.task.state.command.copy()  # the task's arrays change later
        kicks = drawn.kicks if np.logical_or.reduce(drawn.push) else None
        unstable = self.sim.step(targets, force, drawn.force_target, kicks, self.task.other_forces)
        out = self.task.after_physics(self.sim.sensordata, unstable)
        ended = np.flatnonzero(out.terminated | out.truncated) if autoreset else ()
        if len(ended):  # the step's observations stay as they are: the reset writes into new arrays
            self.reset(ended)
        state = self.task.state
        return BatchStep(
            out,
            force,
            command,
            state.policy_obs,
            state.critic_obs,
            state.command,
            level,
            self.task.task.reward_names,
        )

    def close(self) -> None:
        self.sim.close()
