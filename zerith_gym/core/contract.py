"""The robots contract: what `ZerithVecEnv` asks of a simulation backend, and the checks they share.

Three backends implement it: `zerith_gym.cpu.batch.ZerithBatch` (every robot in this process),
`zerith_gym.cpu.workers.WorkerPool` (slices of robots in worker processes) and `zerith_gym.mjx.MjxBatch`
(MuJoCo MJX on JAX's device). Observations, commands and steps go in and out as numpy arrays with a leading
robot axis, so the vec env, SB3 and RL Zoo never see which one runs.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import NamedTuple, Protocol

import numpy as np

from zerith_gym.core.scenarios import Scenario
from zerith_gym.core.task import StepOutput
from zerith_gym.terrain.levels import LevelRule


class BatchStep(NamedTuple):
    """One control step of n robots, with the robots whose episode ended already reset."""

    out: StepOutput  # the step; its observations are the terminal ones of the robots that ended
    force: np.ndarray  # (n, 3) external force on each target body during the step
    command: np.ndarray  # (n, 3) command during the step
    policy_obs: np.ndarray  # (n, POLICY_SIZE) observations to act on next: after the reset where ended
    critic_obs: np.ndarray  # (n, CRITIC_SIZE)
    next_command: np.ndarray  # (n, 3) command of the next step (a new episode's where ended)
    terrain_level: np.ndarray  # (n,) int, the terrain level (tile row) each robot walked on in the step
    reward_names: tuple[str, ...]  # the columns of `out.terms` (the task's reward terms)


class Robots(Protocol):
    """n robots reset and stepped together."""

    num_robots: int
    scenario: Scenario
    """The scenario the robots follow now (`set_scenario` changes it)."""

    def seed(self, seeds: Mapping[int, np.random.Generator]) -> None:
        """Random generators for the next resets (robot index -> generator)."""

    def reset(
        self,
        ids: np.ndarray,
        commands: Mapping[int, np.ndarray] | None = None,
        tiles: Mapping[int, tuple[int, int]] | None = None,
    ) -> tuple[np.ndarray, np.ndarray]:
        """New episodes of robots `ids` (`commands` fixes some robots' commands, `tiles` the (level, kind
        column) some start on, on a tile terrain); their policy and critic observations."""

    @property
    def commands(self) -> np.ndarray:
        """The current command of every robot, (n, 3)."""

    def step(self, actions: np.ndarray) -> BatchStep:
        """One control step of every robot with checked actions (n, 12); ended episodes restart."""

    def set_scenario(self, scenario: Scenario) -> None:
        """Follow `scenario` from now on (`check_scenario_change` says which changes are possible)."""

    def set_level_rule(self, rule: LevelRule | None) -> None:
        """Move robots between terrain levels by `rule` when their episodes end (None: stop)."""

    def close(self) -> None:
        """Stop whatever runs beside this process (workers, threads); safe to call twice."""


def check_num_robots(num_robots: object) -> int:
    """`num_robots` as an int; ValueError unless it is a positive integer."""
    if not isinstance(num_robots, int | np.integer) or isinstance(num_robots, bool) or num_robots < 1:
        raise ValueError(f"the number of robots must be a positive integer, got {num_robots!r}")
    return int(num_robots)


def check_scenario_change(current: Scenario, new: Scenario) -> None:
    """ValueError unless an env built for `current` can follow `new` (the same terrain)."""
    if not isinstance(new, Scenario):
        raise ValueError(f"expected a Scenario, got {new!r}")
    if new.terrain != current.terrain:
        raise ValueError(
            f"scenario {new.name!r} has another terrain than {current.name!r}: only randomization, "
            "forces, pushes and commands can change in an env; make a new env instead"
        )
