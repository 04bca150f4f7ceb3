"""Zerith-1 robot constants: joint order, default pose, actuation, bodies and timing.

Everything about the robot that the task needs lives here, apart from the task logic, so a different
robot can be plugged in by writing another module like this one (and its MJCF).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

ASSET_PATH = Path(__file__).resolve().parent / "assets" / "zerith1.xml"

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
FOOT_GEOMS = ("left_foot", "right_foot")
FOOT_SOLE_HALF_LENGTH = 0.11
"""Half length (m) of the foot box; used to place the robot above the ground at reset."""

STANDING_HEIGHT = 0.745
"""Pelvis height (m) above the ground when standing still in the default pose."""
HIP_WIDTH = 0.2
"""Lateral distance (m) between the two hip joints: the nominal stance width."""

PHYSICS_DT = 0.005
"""Physics time step (s): the largest that the stability tests pass with margin."""
CONTROL_DT = 0.02
"""Policy period (s): 50 Hz."""
DECIMATION = round(CONTROL_DT / PHYSICS_DT)


def sensor_slices(model) -> dict[str, slice]:
    """Map each sensor name of `model` to its slice of `data.sensordata`."""
    import mujoco

    slices = {}
    for i in range(model.nsensor):
        name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_SENSOR, i)
        start = int(model.sensor_adr[i])
        slices[name] = slice(start, start + int(model.sensor_dim[i]))
    return slices
