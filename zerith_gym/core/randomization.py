"""Domain randomization: ranges (paper Tables 5 and 6) and per-episode sampling from uniform numbers.

A sample is a `DomainParams` of arrays with a leading batch axis, computed from uniform numbers that each
robot draws from its own random generator, always the same amount (even for degenerate ranges), so a
batch of robots reproduces the same robots simulated one by one.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from zerith_gym.core.arrays import namespace

Range = tuple[float, float]
NUM_LINKS = 16
"""Bodies whose mass is scaled: every robot body except the root (which gets `added_mass` instead)."""
NUM_JOINTS = 12
"""Joints whose motor strength and gains are drawn: every actuated joint. Both robots have 16 links and 12
joints, so that one domain vector serves them (`NominalModel.capture` checks a model against both)."""


@dataclass(frozen=True)
class RandomizationRanges:
    """Uniform ranges of every randomized quantity. Defaults are the nominal robot (no randomization)."""

    friction: Range = (1.0, 1.0)
    """Sliding friction of the soles' material. A foot on the ground slides at `contact_friction` of it: the
    mean with the ground's material (`GROUND_FRICTION`), as in the simulator the paper trained in."""
    added_mass: Range = (0.0, 0.0)
    """Mass (kg) added to the root body (pelvis, trunk, head): a load at the centroid."""
    com_offset: Range = (0.0, 0.0)
    """Offset (m) of the root body's centre of mass, drawn per axis x, y, z."""
    link_mass_scale: Range = (1.0, 1.0)
    """Factor on the mass and inertia of each other body, drawn per body."""
    motor_strength: Range = (1.0, 1.0)
    """Factor on each actuator's output (its PD torque and torque limit), drawn per joint."""
    kp_scale: Range = (1.0, 1.0)
    kd_scale: Range = (1.0, 1.0)
    action_delay: Range = (0.0, 0.0)
    """Delay (s) between the policy's action and the actuators, rounded to physics steps."""
    init_joint_scale: Range = (1.0, 1.0)
    """Factor on each default joint position at reset."""
    init_roll_pitch: float = 0.0
    """Half width (rad) of the uniform base roll and pitch at reset."""
    push_velocity: Range = (0.0, 0.0)
    """Magnitude (m/s) of the horizontal velocity kick given to the base every `push_interval_s`."""
    push_interval_s: float = 8.0
    observation_noise: float = 0.0
    """Factor on the policy observation noise scales (0 = noiseless, 1 = training noise)."""


NOMINAL = RandomizationRanges()
TRAIN = RandomizationRanges(
    friction=(0.1, 1.5),
    added_mass=(-2.0, 5.0),
    com_offset=(-0.07, 0.1),
    link_mass_scale=(0.8, 1.4),
    motor_strength=(0.9, 1.1),
    kp_scale=(0.85, 1.15),
    kd_scale=(0.85, 1.15),
    action_delay=(0.0, 0.04),
    init_joint_scale=(0.5, 1.5),
    init_roll_pitch=0.1,
    push_velocity=(0.0, 0.5),
    observation_noise=1.0,
)
"""Training ranges: paper Table 5 (left column) and Table 6."""
TEST_LOAD: Range = (-3.0, 8.0)
TEST_FRICTION: Range = (0.1, 2.0)
TEST_COM: Range = (-0.07, 0.1)
WIDEST = RandomizationRanges(
    **{name: getattr(TRAIN, name) for name in ("link_mass_scale", "motor_strength", "kp_scale", "kd_scale")},
    friction=TEST_FRICTION,
    added_mass=TEST_LOAD,
    com_offset=TEST_COM,
    action_delay=TRAIN.action_delay,
)
"""Every domain parameter's widest range in the paper (training or test): the critic sees each scaled from
this range to [-1, 1] (`zerith_gym.zerith1.observations.CRITIC_SCALE`)."""


@dataclass
class DomainParams:
    """Sampled physical parameters of n robots (leading axis n; numpy or JAX arrays)."""

    friction: np.ndarray  # (n, 1)
    added_mass: np.ndarray  # (n, 1)
    com_offset: np.ndarray  # (n, 3)
    link_mass_scale: np.ndarray  # (n, NUM_LINKS)
    motor_strength: np.ndarray  # (n, 12)
    kp_scale: np.ndarray  # (n, 12)
    kd_scale: np.ndarray  # (n, 12)
    action_delay: np.ndarray  # (n, 1), seconds

    @staticmethod
    def from_vector(vector: np.ndarray) -> DomainParams:
        """Views of the columns of `vector` (n, DOMAIN_VECTOR_SIZE) (the critic's layout) as parameters."""
        params, start = {}, 0
        for name, size in DOMAIN_SIZES.items():
            params[name] = vector[:, start : start + size]
            start += size
        return DomainParams(**params)


DOMAIN_SIZES = {
    "friction": 1,
    "added_mass": 1,
    "com_offset": 3,
    "link_mass_scale": NUM_LINKS,
    "motor_strength": NUM_JOINTS,
    "kp_scale": NUM_JOINTS,
    "kd_scale": NUM_JOINTS,
    "action_delay": 1,
}
DOMAIN_VECTOR_SIZE = sum(DOMAIN_SIZES.values())
DOMAIN_DRAWS = DOMAIN_VECTOR_SIZE
"""Uniform numbers in [0, 1) consumed by one robot's domain parameters: one per value."""


def uniform_in(bounds: Range | tuple[np.ndarray, np.ndarray], uniforms: np.ndarray) -> np.ndarray:
    """Map uniforms in [0, 1) onto [low, high), exactly as `Generator.uniform(low, high)` does.

    `low` and `high` are numbers or arrays broadcasting against `uniforms`.
    """
    low, high = bounds
    return low + (high - low) * uniforms


def domain_bounds(ranges: RandomizationRanges) -> tuple[np.ndarray, np.ndarray]:
    """Lower and upper bound of each entry of the domain vector, (DOMAIN_VECTOR_SIZE,) each."""
    bounds = np.repeat([getattr(ranges, name) for name in DOMAIN_SIZES], list(DOMAIN_SIZES.values()), axis=0)
    return bounds[:, 0], bounds[:, 1]


def delay_lags(action_delay: np.ndarray, physics_dt: float, decimation: int) -> np.ndarray:
    """For each robot and physics sub-step, how many control steps old the applied action is, (n, decimation).

    With a delay of d sub-steps, sub-step j of a control step applies the action of
    -floor((j - d) / decimation) control steps ago (0 = the current one).
    """
    xp = namespace(action_delay)
    delay_steps = xp.rint(action_delay[:, 0] / physics_dt).astype(int)
    substeps = np.arange(decimation)
    return -xp.floor_divide(substeps[None, :] - delay_steps[:, None], decimation)
