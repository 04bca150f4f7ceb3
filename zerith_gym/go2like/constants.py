"""Go2-like quadruped constants: joint order, default pose, actuation, bodies, sensors and timing.

The quadruped counterpart of `zerith_gym.zerith1.constants`, for the model in `go2like.xml` (a
Unitree-Go2-like robot built from the Go2's published figures, with legged_gym's Go2 settings). Every constant
here must match that MJCF: joint names and order, ranges, PD gains and torque limits, masses, body and geom
names, the time step and the `home` keyframe (checked by tests/test_quadruped_model.py).
"""

from __future__ import annotations

from pathlib import Path
from typing import NamedTuple

import numpy as np

from zerith_gym.core.spec import RobotSpec

ASSET_PATH = Path(__file__).resolve().parent / "go2like.xml"

LEGS = ("FL", "FR", "RL", "RR")
"""Front left, front right, rear left, rear right: legged_gym's Go2 order."""
LEG_JOINTS = ("hip", "thigh", "calf")
"""Per leg: hip abduction (about x), thigh (about y), calf or knee (about y)."""
JOINT_NAMES = tuple(f"{leg}_{joint}" for leg in LEGS for joint in LEG_JOINTS)
"""The 12 actuated joints, in action/observation order: FL, FR, RL, RR, each hip, thigh, calf."""
NUM_JOINTS = len(JOINT_NAMES)

_HIP_RANGE = (-1.0472, 1.0472)
_FRONT_THIGH_RANGE = (-1.5708, 3.4907)
_REAR_THIGH_RANGE = (-0.5236, 4.5379)
_CALF_RANGE = (-2.7227, -0.83776)
JOINT_RANGE = np.array(
    [_HIP_RANGE, _FRONT_THIGH_RANGE, _CALF_RANGE] * 2 + [_HIP_RANGE, _REAR_THIGH_RANGE, _CALF_RANGE] * 2
)
"""(12, 2) lower and upper limit (rad) of each joint; also the actuators' control range."""

DEFAULT_JOINT_POS = np.array([0.1, 0.8, -1.5, -0.1, 0.8, -1.5, 0.1, 1.0, -1.5, -0.1, 1.0, -1.5])
"""legged_gym's Go2 default pose (rad): hips splayed outward by 0.1, knees bent backward. Actions are
offsets from this pose. Commanded with kp 20, the robot's weight bends the joints by up to 0.35 rad away
from it (the `home` keyframe)."""

ACTION_SCALE = np.full(NUM_JOINTS, 0.25)
"""Joint-position offset (rad) produced by an action of +-1, per joint."""

ACTION_CLIP = 100.0
"""legged_gym's `clip_actions`: actions reach +-100 (+-25 rad of offset, so the torque limits bound them,
not the clip). A clip at 1 (+-0.25 rad) holds the joints closer to the default pose than the robot's own
weight bends them with kp 20 (up to 0.35 rad): a policy trained so saturated its actions and stood still."""

# PD gains and torque limits: these must match the MJCF <default> classes (checked by the tests).
KP = np.full(NUM_JOINTS, 20.0)
KD = np.full(NUM_JOINTS, 0.5)
TORQUE_LIMIT = np.array([23.7, 23.7, 45.43] * 4)

TOTAL_MASS = 15.205
"""Total mass (kg): trunk 6.921, and per leg hip 0.678, thigh 1.152, calf 0.201, foot 0.04."""

ROOT_BODY = "trunk"
"""Root body carrying the trunk with battery and electronics: the robot's "centroid" for external forces."""
FOOT_BODIES = tuple(f"{leg}_foot" for leg in LEGS)
FOOT_GEOMS = FOOT_BODIES
"""The foot spheres, one per leg in `LEGS` order: the only geoms touching the ground."""
FOOT_RADIUS = 0.022
"""Radius (m) of the foot spheres; foot positions (the `*_foot` sites, sensors) are their centres."""

STANDING_HEIGHT = 0.2645
"""Trunk height (m) above the ground when standing still under the default-pose command (`home` keyframe).

With the default pose held exactly and the feet on the ground, the trunk would be at 0.32 m; kp 20 lets the
robot's weight lower it to this height."""
HIP_WIDTH = 0.093
"""Lateral distance (m) between the left and right hip (abduction) joints."""
HIP_LENGTH = 0.3868
"""Longitudinal distance (m) between the front and rear hip joints."""
STANCE_WIDTH = 0.354
"""Lateral distance (m) between the left and right feet in the `home` stance: the nominal stance width."""

PHYSICS_DT = 0.005
"""Physics time step (s), as legged_gym's Go2 configuration."""
CONTROL_DT = 0.02
"""Policy period (s): 50 Hz."""
DECIMATION = round(CONTROL_DT / PHYSICS_DT)

HOME_KEYFRAME = "home"
"""The MJCF keyframe of the robot standing still on the floor, with the default pose as its control."""

SENSOR_GROUPS: dict[str, tuple[str, ...]] = {
    "base_pos": ("base_pos",),
    "base_heading": ("base_heading",),
    "base_up": ("base_up",),
    "base_linvel": ("base_linvel",),
    "base_angvel": ("base_angvel",),
    "joint_pos": tuple(f"{joint}_pos" for joint in JOINT_NAMES),
    "joint_vel": tuple(f"{joint}_vel" for joint in JOINT_NAMES),
    "joint_torque": tuple(f"{joint}_torque" for joint in JOINT_NAMES),
    "foot_pos": tuple(f"{foot}_pos" for foot in FOOT_BODIES),
    "foot_linvel": tuple(f"{foot}_linvel" for foot in FOOT_BODIES),
    "foot_force": tuple(f"{foot}_force" for foot in FOOT_BODIES),
    "base_contact": ("base_contact",),
    "leg_contact": tuple(f"{leg}_{link}_contact" for leg in LEGS for link in ("thigh", "calf")),
}
"""Each quantity a task reads, and the MJCF sensors it is made of (contiguous, in this order)."""


class Sensors(NamedTuple):
    """The quadruped's readings, one field per quantity of `SENSOR_GROUPS`; in the world frame unless noted.

    As a layout (`RobotSpec.sensor_layout`), each field is a slice of `data.sensordata`; as readings of n
    robots (`zerith_gym.core.spec.read_sensors`), each is an (n, width) view of their sensor rows. Feet are
    in `LEGS` order.
    """

    base_pos: np.ndarray  # (3) trunk position
    base_heading: np.ndarray  # (3) trunk x axis
    base_up: np.ndarray  # (3) world z axis in the trunk frame
    base_linvel: np.ndarray  # (3) trunk frame
    base_angvel: np.ndarray  # (3) trunk frame
    joint_pos: np.ndarray  # (12)
    joint_vel: np.ndarray  # (12)
    joint_torque: np.ndarray  # (12) actuator forces
    foot_pos: np.ndarray  # (12) each foot sphere's centre, xyz
    foot_linvel: np.ndarray  # (12) xyz per foot
    foot_force: np.ndarray  # (12) ground reaction on each foot, xyz
    base_contact: np.ndarray  # (1) contacts between the trunk and the ground (> 0: touching)
    leg_contact: np.ndarray  # (8) contacts of each thigh and calf with the ground, FL thigh, FL calf, ...


GO2LIKE = RobotSpec(
    name="go2like",
    display_name="Go2-like quadruped",
    asset_path=ASSET_PATH,
    joint_names=JOINT_NAMES,
    default_joint_pos=DEFAULT_JOINT_POS,
    action_scale=ACTION_SCALE,
    kp=KP,
    kd=KD,
    torque_limit=TORQUE_LIMIT,
    total_mass=TOTAL_MASS,
    root_body=ROOT_BODY,
    force_bodies={"centroid": (ROOT_BODY,), "hands": (), "feet": FOOT_BODIES},
    contact_geoms=FOOT_GEOMS,
    foot_bodies=FOOT_BODIES,
    standing_height=STANDING_HEIGHT,
    physics_dt=PHYSICS_DT,
    control_dt=CONTROL_DT,
    sensors=Sensors,
    sensor_groups=SENSOR_GROUPS,
    action_clip=ACTION_CLIP,
)
"""The Go2-like quadruped as the shared machinery reads it (`zerith_gym.core.spec.RobotSpec`)."""
