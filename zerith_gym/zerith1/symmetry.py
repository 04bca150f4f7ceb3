"""Zerith-1's left-right mirror symmetry, as maps of the actor's observation and of the action.

The robot, its default stance, joint ranges, gains and the task are symmetric about the base's x-z plane, so
a state reflected left-to-right calls for the reflected action. Reflecting swaps the legs, flips the sign of
the lateral and turning quantities (roll, yaw, their rates, the sideways and turning commands, the hip yaw,
hip roll and ankle roll joints, whose axes are the same on both legs) and moves the gait clock by half a
period (the right foot runs half a period after the left, `zerith_gym.zerith1.gait`). Each map is a signed
permutation: ``mirrored[..., i] = sign[i] * x[..., index[i]]``, its own inverse. A symmetry loss
(`HuRiPPO(mirror_coef=...)`) asks the actor to act on a mirrored observation as it acts on the original,
mirrored. The critic's observation is not mapped: the domain parameters and height samples carry sides of
their own, and the critic needs no symmetry to learn.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from zerith_gym.core.observations import layout_slices
from zerith_gym.zerith1 import constants as robot
from zerith_gym.zerith1.observations import POLICY_LAYOUT, POLICY_SIZE

LATERAL_JOINTS = ("hip_yaw", "hip_roll", "ankle_roll")
"""Leg joints whose angle changes sign under the mirror (rotations about the x or z axis)."""


@dataclass(frozen=True)
class SignedPermutation:
    """``x -> sign * x[..., index]``: a mirror map over the last axis of an array."""

    index: np.ndarray
    sign: np.ndarray

    def __post_init__(self) -> None:
        if sorted(self.index.tolist()) != list(range(len(self.index))) or self.sign.shape != self.index.shape:
            raise ValueError("a signed permutation needs a permutation `index` and one sign per entry")

    def __call__(self, x: np.ndarray) -> np.ndarray:
        return x[..., self.index] * self.sign


def _joint_mirror() -> SignedPermutation:
    """Left and right legs swapped, lateral joints negated (the order of `robot.JOINT_NAMES`)."""
    names = list(robot.JOINT_NAMES)
    other = {"left": "right", "right": "left"}
    index, sign = [], []
    for name in names:
        side, joint = name.split("_", 1)
        index.append(names.index(f"{other[side]}_{joint}"))
        sign.append(-1.0 if joint in LATERAL_JOINTS else 1.0)
    return SignedPermutation(np.array(index), np.array(sign))


BLOCK_SIGNS = {
    "base_roll_pitch": (-1.0, 1.0),
    "base_angular_velocity": (-1.0, 1.0, -1.0),
    "clock_sin_cos": (-1.0, -1.0),  # half a period later
    "command": (1.0, -1.0, -1.0),
}
"""The sign of each entry of the policy blocks that stay in place under the mirror."""
JOINT_BLOCKS = ("joint_position_offset", "joint_velocity", "last_action")
"""The policy blocks with one entry per joint, mirrored as the action is."""


def _policy_mirror(joints: SignedPermutation) -> SignedPermutation:
    """Every block of `POLICY_LAYOUT` by its rule (KeyError for a block without one)."""
    index, sign = np.arange(POLICY_SIZE), np.ones(POLICY_SIZE)
    for name, block in layout_slices(POLICY_LAYOUT).items():
        if name in JOINT_BLOCKS:
            index[block], sign[block] = block.start + joints.index, joints.sign
        else:
            sign[block] = BLOCK_SIGNS[name]
    return SignedPermutation(index, sign)


ACTION_MIRROR = _joint_mirror()
"""The mirror of an action (12 joint offsets)."""
POLICY_MIRROR = _policy_mirror(ACTION_MIRROR)
"""The mirror of the actor's observation (`POLICY_LAYOUT`)."""
