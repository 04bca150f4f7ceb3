"""Zerith-1's observation layouts of the actor ("policy") and the privileged critic ("critic"), and the
critic's scales.

Each layout is a sequence of (name, size) blocks (`zerith_gym.core.observations.layout_slices` turns it into
index ranges, which the documentation tables are generated from, so code and docs agree).

The actor's observation is in physical units, for a running normalizer (`VecNormalize`) and the deployed
actor, which carries that normalizer. The critic's comes out of the env already scaled by known ranges
(`CRITIC_OFFSET`, `CRITIC_SCALE`), legged-robot style: every domain parameter from its widest range in the
paper to [-1, 1], the external force by the largest test force, contact forces by the body weight. Running
statistics cannot scale those inputs: they are constant while a curriculum holds their ranges closed, and
a normalizer that saw them constant saturates when the ranges open. `critic_in_units` undoes the scaling.
"""

from __future__ import annotations

import numpy as np

from zerith_gym.core.observations import HEIGHT_SCALE, MAX_EXTERNAL_FORCE, layout_slices
from zerith_gym.core.randomization import DOMAIN_SIZES, DOMAIN_VECTOR_SIZE, WIDEST, domain_bounds
from zerith_gym.zerith1 import constants as robot

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
CRITIC_DOMAIN = slice(CRITIC_SIZE - DOMAIN_VECTOR_SIZE, CRITIC_SIZE)
"""The critic's domain-parameter block (its last), laid out as `DomainParams.from_vector` reads it."""

POLICY_NOISE = {
    "base_roll_pitch": 0.05,
    "base_angular_velocity": 0.2,
    "joint_position_offset": 0.01,
    "joint_velocity": 1.5,
}
"""Half width of the uniform sensor noise on each policy block in training (units of the block)."""

BODY_WEIGHT = robot.TOTAL_MASS * 9.81
"""The nominal body weight (N): the critic's unit of contact force."""
POLICY_BLOCK_SCALES = {"base_angular_velocity": 0.25, "joint_velocity": 0.05}
"""Factors on the policy's blocks where the critic reads them (rad/s: 4 and 20 to about 1); others 1."""


def policy_noise_scale() -> np.ndarray:
    """Per-entry noise half width (POLICY_SIZE,): zero for the clock, command and last action."""
    scale = np.zeros(POLICY_SIZE)
    slices = layout_slices(POLICY_LAYOUT)
    for name, value in POLICY_NOISE.items():
        scale[slices[name]] = value
    return scale


def _critic_affine() -> tuple[np.ndarray, np.ndarray]:
    offset, scale = np.zeros(CRITIC_SIZE), np.ones(CRITIC_SIZE)
    critic, policy = layout_slices(CRITIC_LAYOUT), layout_slices(POLICY_LAYOUT)
    for name, factor in POLICY_BLOCK_SCALES.items():
        scale[policy[name]] = factor  # policy_noiseless is the critic's first block
    offset[critic["base_height"]] = robot.STANDING_HEIGHT
    scale[critic["base_height"]] = HEIGHT_SCALE
    scale[critic["foot_height_samples"]] = HEIGHT_SCALE
    scale[critic["foot_contact_force"]] = 1.0 / BODY_WEIGHT
    scale[critic["external_force"]] = 1.0 / MAX_EXTERNAL_FORCE
    low, high = domain_bounds(WIDEST)
    offset[CRITIC_DOMAIN] = (low + high) / 2.0
    scale[CRITIC_DOMAIN] = 2.0 / (high - low)
    return offset.astype(np.float32), scale.astype(np.float32)


CRITIC_OFFSET, CRITIC_SCALE = _critic_affine()
"""The critic observation is `(value - CRITIC_OFFSET) * CRITIC_SCALE` of each entry's physical value."""


def critic_in_units(critic: np.ndarray) -> np.ndarray:
    """Critic observations (..., CRITIC_SIZE) back in physical units (N, m, rad, kg, s, ...)."""
    return critic / CRITIC_SCALE + CRITIC_OFFSET
