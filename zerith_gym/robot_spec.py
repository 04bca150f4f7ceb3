"""What the shared simulation machinery needs to know about a robot, declared once per robot.

A `RobotSpec` names a robot's MJCF, its actuated joints and their default pose and action scale, the bodies
that external forces act on, the geoms that touch the ground, and its timing. The physics (`physics.py`,
`simulator.py`) and the task kernel (`task.py`) read these fields instead of one robot's constants, so
that Zerith-1 (`zerith_gym.robot.ZERITH1`) and the Go2-like quadruped (`zerith_gym.quadruped_robot.GO2LIKE`)
run the same step. What a robot's task observes and rewards is its `LocomotionTask`
(`zerith_gym.humanoid_task.HUMANOID_TASK`, `zerith_gym.legged_gym_task.QUADRUPED_TASK`).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np


@dataclass(frozen=True, eq=False)
class RobotSpec:
    """One robot's facts, as the model (`asset_path`) declares them (each robot's tests check the match)."""

    name: str
    display_name: str
    """The robot's name for people (deployment files, figures)."""
    asset_path: Path
    joint_names: tuple[str, ...]
    """The actuated joints, in action and observation order (the actuators' order in the MJCF)."""
    default_joint_pos: np.ndarray
    """(joints,) rad: the pose an action of zero commands; actions are offsets from it."""
    action_scale: np.ndarray
    """(joints,) rad: the joint-position offset of an action of +-1."""
    kp: np.ndarray
    kd: np.ndarray
    torque_limit: np.ndarray
    """(joints,) each: the nominal PD gains (Nm/rad, Nm s/rad) and torque limits (Nm) of the MJCF."""
    total_mass: float
    root_body: str
    """The floating base: the robot's "centroid" for external forces."""
    force_bodies: Mapping[str, tuple[str, ...]]
    """For each force target of `zerith_gym.disturbances.FORCE_TARGET_NAMES`, the bodies it pushes (empty:
    the robot has no such bodies, and a scenario aiming there is rejected)."""
    contact_geoms: tuple[str, ...]
    """The sphere geoms that touch the ground standing: at reset the lowest is placed just above it."""
    foot_bodies: tuple[str, ...]
    standing_height: float
    """Base height (m) above the ground standing still in the default pose."""
    physics_dt: float
    control_dt: float
    sensor_layout: Callable[[Any], Any]
    """`model -> Sensors` layout of slices of `data.sensordata` (each robot's `Sensors.layout`)."""
    action_clip: float = 1.0
    """The action space's bound: actions are clipped to [-action_clip, action_clip], then scaled."""

    @property
    def num_joints(self) -> int:
        return len(self.joint_names)

    @property
    def decimation(self) -> int:
        """Physics steps per control step."""
        return round(self.control_dt / self.physics_dt)

    def force_target_bodies(self, target: str) -> tuple[str, ...]:
        """The bodies a force aimed at `target` acts on; ValueError if this robot has none there."""
        bodies = self.force_bodies.get(target, ())
        if not bodies:
            have = [name for name, names in self.force_bodies.items() if names]
            raise ValueError(f"the {self.name} robot has no {target!r} bodies for forces; it has {have}")
        return bodies
