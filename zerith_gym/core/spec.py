"""What the shared simulation machinery needs to know about a robot, declared once per robot.

A `RobotSpec` names a robot's MJCF, its actuated joints and their default pose and action scale, the bodies
that external forces act on, the geoms that touch the ground, its sensors and its timing. The physics
(`core/physics.py`, `cpu/simulator.py`) and the task kernel (`core/task.py`) read these fields instead of
one robot's constants, so that Zerith-1 (`zerith_gym.zerith1.constants.ZERITH1`) and the Go2-like quadruped
(`zerith_gym.go2like.constants.GO2LIKE`) run the same step. What a robot's task observes and rewards is its
`LocomotionTask` (`zerith_gym.zerith1.task.HUMANOID_TASK`, `zerith_gym.go2like.task.QUADRUPED_TASK`).
"""

from __future__ import annotations

import itertools
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any, NamedTuple

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
    """For each force target of `zerith_gym.core.disturbances.FORCE_TARGET_NAMES`, the bodies it pushes
    (empty: the robot has no such bodies, and a scenario aiming there is rejected)."""
    contact_geoms: tuple[str, ...]
    """The sphere geoms that touch the ground standing: at reset the lowest is placed just above it."""
    foot_bodies: tuple[str, ...]
    standing_height: float
    """Base height (m) above the ground standing still in the default pose."""
    physics_dt: float
    control_dt: float
    sensors: type[NamedTuple]
    """The robot's readings: a NamedTuple with one field per quantity of `sensor_groups`."""
    sensor_groups: Mapping[str, tuple[str, ...]]
    """Each quantity the task reads, and the MJCF sensors it is made of (contiguous, in this order)."""
    action_clip: float = 1.0
    """The action space's bound: actions are clipped to [-action_clip, action_clip], then scaled."""

    @property
    def num_joints(self) -> int:
        return len(self.joint_names)

    @property
    def decimation(self) -> int:
        """Physics steps per control step."""
        return round(self.control_dt / self.physics_dt)

    def sensor_layout(self, model: Any) -> NamedTuple:
        """The robot's `sensors` as slices of `data.sensordata` of `model`, one per quantity (`read_sensors`
        reads them); ValueError if a quantity's sensors are not contiguous in the model."""
        return self.sensors(**sensor_blocks(model, self.sensor_groups))

    def force_target_bodies(self, target: str) -> tuple[str, ...]:
        """The bodies a force aimed at `target` acts on; ValueError if this robot has none there."""
        bodies = self.force_bodies.get(target, ())
        if not bodies:
            have = [name for name, names in self.force_bodies.items() if names]
            raise ValueError(f"the {self.name} robot has no {target!r} bodies for forces; it has {have}")
        return bodies


def read_sensors(layout: NamedTuple, sensordata: np.ndarray) -> NamedTuple:
    """The readings of n robots from their sensor rows `sensordata` (n, nsensordata), for a layout of slices
    (`RobotSpec.sensor_layout`): each field an (n, width) view, numpy or JAX."""
    return type(layout)(*(sensordata[:, block] for block in layout))


def sensor_slices(model: Any) -> dict[str, slice]:
    """Map each sensor name of `model` to its slice of `data.sensordata`."""
    import mujoco

    slices = {}
    for i in range(model.nsensor):
        name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_SENSOR, i)
        start = int(model.sensor_adr[i])
        slices[name] = slice(start, start + int(model.sensor_dim[i]))
    return slices


def sensor_blocks(model: Any, groups: Mapping[str, tuple[str, ...]]) -> dict[str, slice]:
    """For each quantity of `groups` (its sensors' names, in order), its slice of `data.sensordata`;
    ValueError if a quantity's sensors are not contiguous in the model."""
    slices = sensor_slices(model)
    blocks = {}
    for quantity, names in groups.items():
        parts = [slices[name] for name in names]
        if any(a.stop != b.start for a, b in itertools.pairwise(parts)):
            raise ValueError(f"sensors {names} must be contiguous in the model")
        blocks[quantity] = slice(parts[0].start, parts[-1].stop)
    return blocks
