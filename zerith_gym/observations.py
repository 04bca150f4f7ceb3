"""Observation layouts of the actor ("policy") and the privileged critic ("critic").

Each layout is a sequence of (name, size) blocks; `layout_slices` turns it into index ranges, which the
documentation tables are generated from, so code and docs agree.
"""

from __future__ import annotations

import numpy as np

from zerith_gym import robot
from zerith_gym.randomization import DOMAIN_SIZES

HEIGHT_SAMPLE_OFFSETS = np.array([(dx, dy) for dx in (-0.1, 0.0, 0.1) for dy in (-0.1, 0.0, 0.1)])
"""Height-sample points around each foot (m, in the base's yaw frame): a 3 x 3 grid, 0.1 m apart."""

POLICY_LAYOUT: tuple[tuple[str, int], ...] = (
    ("base_roll_pitch", 2),
    ("base_angular_velocity", 3),
    ("clock_sin_cos", 2),
    ("command", 3),
    ("joint_position_offset", robot.NUM_JOINTS),
    ("joint_velocity", robot.NUM_JOINTS),
    ("last_action", robot.NUM_JOINTS),
)
CRITIC_LAYOUT: tuple[tuple[str, int], ...] = (
    ("policy_noiseless", sum(size for _, size in POLICY_LAYOUT)),
    ("base_linear_velocity", 3),
    ("base_height", 1),
    ("foot_height_samples", 2 * len(HEIGHT_SAMPLE_OFFSETS)),
    ("foot_contact", 2),
    ("foot_contact_force", 6),
    ("desired_contact", 2),
    ("external_force", 3),
    *((f"domain_{name}", size) for name, size in DOMAIN_SIZES.items()),
)
POLICY_SIZE = sum(size for _, size in POLICY_LAYOUT)
CRITIC_SIZE = sum(size for _, size in CRITIC_LAYOUT)

POLICY_NOISE = {
    "base_roll_pitch": 0.05,
    "base_angular_velocity": 0.2,
    "joint_position_offset": 0.01,
    "joint_velocity": 1.5,
}
"""Half width of the uniform sensor noise on each policy block in training (units of the block)."""


def layout_slices(layout: tuple[tuple[str, int], ...]) -> dict[str, slice]:
    """Index range of each block of `layout`."""
    slices, start = {}, 0
    for name, size in layout:
        slices[name] = slice(start, start + size)
        start += size
    return slices


def policy_noise_scale() -> np.ndarray:
    """Per-entry noise half width (POLICY_SIZE,): zero for the clock, command and last action."""
    scale = np.zeros(POLICY_SIZE)
    slices = layout_slices(POLICY_LAYOUT)
    for name, value in POLICY_NOISE.items():
        scale[slices[name]] = value
    return scale
