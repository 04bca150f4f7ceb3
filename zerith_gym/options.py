"""The options every Zerith env takes (`ZerithOptions`, declared once) and their checks: observation modes,
robots, scenarios, reward weights, reset options and commands. The spaces are in `zerith_gym.core.spaces`."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, fields
from typing import Any

import numpy as np

from zerith_gym.core.scenarios import Scenario, resolve_scenario
from zerith_gym.core.task import EPISODE_STEPS, LocomotionTask
from zerith_gym.robots import locomotion_task

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


@dataclass(frozen=True)
class ZerithOptions:
    """The task options of every Zerith env (`gym.make("Zerith1-v0", ...)`, `Zerith1Env`, `ZerithVecEnv`).

    Checked on construction: a bad value raises ValueError saying what is allowed.
    """

    scenario: str | Scenario | None = None
    """A name in `zerith_gym.SCENARIOS`, or a custom `Scenario`; None: the robot's training scenario
    ("train" for Zerith-1, "quadruped-train" for the quadruped)."""
    obs_mode: str = "dict"
    """"dict": `Dict(policy=Box(46), critic=Box(139))`; "policy": the 46-d policy Box alone."""
    command: tuple[float, float, float] | None = None
    """A fixed (vx, vy, yaw rate) for every episode; None: the scenario's (drawn in train and nominal)."""
    reward_weights: Mapping[str, float] | None = None
    """Overrides of `zerith_gym.DEFAULT_REWARD_WEIGHTS`, by term name."""
    terrain_seed: int = 0
    """Seed of the height field's heights, uneven or tiles (fixed for the env's lifetime)."""
    episode_steps: int = EPISODE_STEPS
    """Control steps before the time-out truncation (1000: 20 s)."""
    robot: str = "zerith1"
    """Which robot (`zerith_gym.robots.ROBOT_TASKS`): "zerith1", or "go2like" (the `Go2Like-v0` env's)."""

    def __post_init__(self) -> None:
        if self.obs_mode not in OBS_MODES:
            raise ValueError(f"unknown obs_mode {self.obs_mode!r}; valid values: {', '.join(OBS_MODES)}")
        task = locomotion_task(self.robot)
        scenario = self.resolved_scenario
        for target in scenario.force.targets:
            task.robot.force_target_bodies(target)
        if self.command is not None:
            check_command(self.command, "command")
        resolve_reward_weights(self.reward_weights, task.reward_weights)
        if not isinstance(self.episode_steps, int | np.integer) or self.episode_steps < 1:
            raise ValueError(f"episode_steps must be a positive integer, got {self.episode_steps!r}")

    @classmethod
    def from_kwargs(cls, kwargs: Mapping[str, Any], where: str = "Zerith1-v0") -> ZerithOptions:
        """Options from keyword arguments; ValueError naming the unknown ones and the valid ones."""
        names = [f.name for f in fields(cls)]
        unknown = sorted(set(kwargs) - set(names))
        if unknown:
            raise ValueError(f"unknown {where} option(s) {unknown}; valid options: {', '.join(names)}")
        return cls(**kwargs)

    @property
    def task(self) -> LocomotionTask:
        """The robot's task: what it observes and is rewarded for."""
        return locomotion_task(self.robot)

    @property
    def resolved_scenario(self) -> Scenario:
        return resolve_scenario(self.task.default_scenario if self.scenario is None else self.scenario)

    def fixed_command(self, scenario: Scenario) -> tuple[float, float, float] | None:
        """The fixed command of every episode in `scenario`, if any: the option's, else the scenario's."""
        if self.command is not None:
            return tuple(check_command(self.command, "command").tolist())
        return scenario.command


def resolve_reward_weights(
    overrides: Mapping[str, float] | None, defaults: Mapping[str, float]
) -> np.ndarray:
    """The weight vector (K,) in the order of `defaults` (a task's terms and weights) with `overrides`
    applied; ValueError on an unknown term or a non-finite weight."""
    weights = dict(defaults)
    for name, value in (overrides or {}).items():
        if name not in weights:
            raise ValueError(
                f"unknown reward term {name!r} in reward_weights; valid terms: {', '.join(defaults)}"
            )
        value = float(value)
        if not np.isfinite(value):
            raise ValueError(f"reward_weights[{name!r}] must be finite, got {value}")
        weights[name] = value
    return np.array([weights[name] for name in defaults])


def reset_command(options: Mapping[str, Any] | None, also_valid: tuple[str, ...] = ()) -> np.ndarray | None:
    """The episode's command from reset `options` (None if not given); ValueError on options other than
    `RESET_OPTIONS` and the caller's `also_valid`."""
    options = dict(options or {})
    unknown = set(options) - set(RESET_OPTIONS) - set(also_valid)
    if unknown:
        valid = ", ".join((*RESET_OPTIONS, *also_valid))
        raise ValueError(f"unknown reset option(s) {sorted(unknown)}; valid options: {valid}")
    if "command" not in options:
        return None
    return check_command(options["command"], "options['command']")
