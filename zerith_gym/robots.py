"""The robots the envs can simulate, by name, each with its task (`LocomotionTask`)."""

from __future__ import annotations

from zerith_gym.core.task import LocomotionTask
from zerith_gym.go2like.task import QUADRUPED_TASK
from zerith_gym.zerith1.task import HUMANOID_TASK

ROBOT_TASKS: dict[str, LocomotionTask] = {"zerith1": HUMANOID_TASK, "go2like": QUADRUPED_TASK}
"""Each robot's name (the envs' `robot` option) and its task."""


def locomotion_task(robot: str) -> LocomotionTask:
    """The task of the robot called `robot`; ValueError listing the valid names otherwise."""
    if robot not in ROBOT_TASKS:
        raise ValueError(f"unknown robot {robot!r}; valid robots: {', '.join(ROBOT_TASKS)}")
    return ROBOT_TASKS[robot]
