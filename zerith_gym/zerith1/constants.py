"""Zerith-1 robot constants: joint order, default pose, actuation, bodies, sensors and timing.

Everything about the robot that the task needs lives here, apart from the task logic (`zerith1/task.py`);
`ZERITH1` hands it to the shared machinery. Every constant must match the MJCF (`zerith1.xml`).
"""

from __future__ import annotations

from pathlib import Path
from typing import NamedTuple

import numpy as np

from zerith_gym.core.spec import RobotSpec

ASSET_PATH = Path(__file__).resolve().parent / "zerith1.xml"

LEG_JOINTS = ("hip_yaw", "hip_roll", "hip_pitch", "knee", "ankle_pitch", "ankle_roll")
SIDES = ("left", "right")
JOINT_NAMES = tuple(f"{side}_{joint}" for side in SIDES for joint in LEG_JOINTS)
"""The 12 actuated joints, in action/observation order: left leg then right leg."""
NUM_JOINTS = len(JOINT_NAMES)

DEFAULT_JOINT_POS = np.array([0.0, 0.0, -0.25, 0.5, -0.25, 0.0] * 2)
"""Default stance (rad): slightly bent knees, feet flat. Actions are offsets from this pose."""

ACTION_SCALE = np.array([0.4, 0.4, 0.8, 1.0, 0.6, 0.4] * 2)
"""Joint-position offset (rad) produced by an action of +-1, per joint."""

# Nominal PD gains and torque limits: these must match the MJCF <default> classes (checked by the tests).
KP = np.array([100.0, 100.0, 200.0, 350.0, 300.0, 60.0] * 2)
KD = np.array([3.0, 3.0, 5.0, 7.0, 6.0, 2.0] * 2)
TORQUE_LIMIT = np.array([60.0, 100.0, 120.0, 150.0, 60.0, 40.0] * 2)

TOTAL_MASS = 36.0
"""Nominal total mass (kg)."""

ROOT_BODY = "pelvis"
"""Root body carrying pelvis, trunk and head: the robot's "centroid" for external forces."""
HAND_BODIES = ("left_hand", "right_hand")
FOOT_BODIES = ("left_foot", "right_foot")
SOLE_CORNERS = ("heel_left", "heel_right", "toe_left", "toe_right")
SOLE_GEOMS = tuple(tuple(f"{side}_sole_{corner}" for corner in SOLE_CORNERS) for side in SIDES)
"""Per foot (left, right), the sphere geoms at the corners of the sole: the only geoms touching the ground."""
STANDING_HEIGHT = 0.745
"""Pelvis height (m) above the ground when standing still in the default pose."""
HIP_WIDTH = 0.2
"""Lateral distance (m) between the two hip joints: the nominal stance width."""

PHYSICS_DT = 0.005
"""Physics time step (s): the largest that the stability tests pass with margin."""
CONTROL_DT = 0.02
"""Policy period (s): 50 Hz."""
DECIMATION = round(CONTROL_DT / PHYSICS_DT)


_FEET = tuple(f"{side}_foot" for side in SIDES)
SENSOR_GROUPS: dict[str, tuple[str, ...]] = {
    "base_pos": ("base_pos",),
    "base_heading": ("base_heading",),
    "base_up": ("base_up",),
    "base_linvel": ("base_linvel",),
    "base_angvel": ("base_angvel",),
    "joint_pos": tuple(f"{joint}_pos" for joint in JOINT_NAMES),
    "joint_vel": tuple(f"{joint}_vel" for joint in JOINT_NAMES),
    "joint_torque": tuple(f"{joint}_torque" for joint in JOINT_NAMES),
    "foot_pos": tuple(f"{foot}_pos" for foot in _FEET),
    "foot_up": tuple(f"{foot}_up" for foot in _FEET),
    "foot_linvel": tuple(f"{foot}_linvel" for foot in _FEET),
    "foot_force": tuple(f"{foot}_force" for foot in _FEET),
    "leg_collision": ("leg_collision",),
}
"""Each quantity the task reads, and the MJCF sensors it is made of (contiguous, in this order)."""


class Sensors(NamedTuple):
    """The robot's readings, one field per quantity of `SENSOR_GROUPS`; all in the world frame unless noted.

    As a layout (`RobotSpec.sensor_layout`), each field is a slice of `data.sensordata`; as readings of n
    robots (`zerith_gym.core.spec.read_sensors`), each is an (n, width) view of their sensor rows.
    """

    base_pos: np.ndarray  # (3) pelvis position
    base_heading: np.ndarray  # (3) pelvis x axis
    base_up: np.ndarray  # (3) world z axis in the pelvis frame
    base_linvel: np.ndarray  # (3) pelvis frame
    base_angvel: np.ndarray  # (3) pelvis frame
    joint_pos: np.ndarray  # (12)
    joint_vel: np.ndarray  # (12)
    joint_torque: np.ndarray  # (12) actuator forces
    foot_pos: np.ndarray  # (6) left xyz, right xyz
    foot_up: np.ndarray  # (6) each sole's z axis: left xyz, right xyz
    foot_linvel: np.ndarray  # (6) left xyz, right xyz
    foot_force: np.ndarray  # (6) ground reaction on each sole: left xyz, right xyz
    leg_collision: np.ndarray  # (1) > 0 when the legs touch


ZERITH1 = RobotSpec(
    name="zerith1",
    display_name="Zerith-1",
    asset_path=ASSET_PATH,
    joint_names=JOINT_NAMES,
    default_joint_pos=DEFAULT_JOINT_POS,
    action_scale=ACTION_SCALE,
    kp=KP,
    kd=KD,
    torque_limit=TORQUE_LIMIT,
    total_mass=TOTAL_MASS,
    root_body=ROOT_BODY,
    force_bodies={"centroid": (ROOT_BODY,), "hands": HAND_BODIES, "feet": FOOT_BODIES},
    contact_geoms=tuple(name for foot in SOLE_GEOMS for name in foot),
    foot_bodies=FOOT_BODIES,
    standing_height=STANDING_HEIGHT,
    physics_dt=PHYSICS_DT,
    control_dt=CONTROL_DT,
    sensors=Sensors,
    sensor_groups=SENSOR_GROUPS,
)
"""Zerith-1 as the shared machinery reads it (`zerith_gym.core.spec.RobotSpec`)."""
