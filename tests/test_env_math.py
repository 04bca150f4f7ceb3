"""Zerith1-v0 building blocks against independent computations: gait, rewards, delays, schedules, terrain."""

from __future__ import annotations

import numpy as np
import pytest

from zerith_gym import SCENARIOS, Zerith1Env
from zerith_gym.core.commands import CommandRanges, command_bounds, commands_from_uniforms
from zerith_gym.core.disturbances import ForceSchedule, horizontal_vectors, schedule_table
from zerith_gym.core.observations import layout_slices
from zerith_gym.core.randomization import NOMINAL, delay_lags
from zerith_gym.core.scenarios import Scenario
from zerith_gym.terrain.ground import UNEVEN, Terrain
from zerith_gym.zerith1 import constants as robot
from zerith_gym.zerith1 import gait
from zerith_gym.zerith1.observations import CRITIC_LAYOUT, CRITIC_SIZE, POLICY_LAYOUT
from zerith_gym.zerith1.rewards import (
    DEFAULT_REWARD_WEIGHTS,
    REWARD_NAMES,
    TERMS,
    RewardInputs,
    reward_terms,
    reward_terms_by_name,
)


def test_gait_schedule_alternates_feet_and_is_smooth():
    phase = np.linspace(0.0, 1.0, 401)[:-1]
    contact = gait.desired_contact(gait.foot_phases(phase))
    assert contact[100, 0] > 0.99 and contact[100, 1] < 0.01  # phase 0.25: left stance, right swing
    assert contact[300, 0] < 0.01 and contact[300, 1] > 0.99
    assert np.abs(np.diff(contact, axis=0)).max() < 0.05  # no jumps, wrap-around included
    assert abs(contact[0, 0] - gait.desired_contact(np.array([[0.9999, 0.5]]))[0, 0]) < 0.01
    height = gait.swing_height_target(gait.foot_phases(phase))
    assert height[:, 0].max() == pytest.approx(gait.SWING_HEIGHT) and height[300, 0] == pytest.approx(
        gait.SWING_HEIGHT
    )
    assert np.all(height[:200, 0] == 0.0)  # no lift in stance


def raibert_targets(
    foot_phase: np.ndarray, command: np.ndarray, stance_width: float, period: float = gait.GAIT_PERIOD
) -> np.ndarray:
    """The cycle table's Raibert column written out: Raibert-heuristic foot positions (n, 2 feet, xy)
    relative to the base, in the base's yaw frame.

    A foot lands ahead of the hip by half the distance the base travels during a stance (at the
    commanded velocity) and leaves it as far behind: offset = (|1 - 2 phi| - 0.5) * v_cmd * period / 2.
    """
    shift = (np.abs(1.0 - 2.0 * foot_phase) - 0.5) * (0.5 * period)  # (n, 2)
    targets = np.empty((*foot_phase.shape, 2))
    targets[..., 0] = shift * command[:, None, 0]
    targets[..., 1] = shift * command[:, None, 1]
    targets[:, 0, 1] += 0.5 * stance_width
    targets[:, 1, 1] -= 0.5 * stance_width
    return targets


def test_raibert_targets_span_the_stance_stride():
    command = np.array([[0.7, 0.2, 0.0]])
    touchdown = raibert_targets(np.array([[0.0, 0.5]]), command, stance_width=0.2)[0]
    liftoff = raibert_targets(np.array([[0.5, 0.0]]), command, stance_width=0.2)[0]
    stride = 0.7 * gait.GAIT_PERIOD / 2  # distance travelled during one stance
    assert touchdown[0, 0] - liftoff[0, 0] == pytest.approx(stride)
    assert touchdown[0, 1] == pytest.approx(0.1 + 0.2 * gait.GAIT_PERIOD / 4)
    assert touchdown[1, 1] == pytest.approx(-0.1 - 0.2 * gait.GAIT_PERIOD / 4)


def test_cycle_table_matches_the_gait_functions():
    table = gait.cycle_table(robot.CONTROL_DT)
    assert len(table) == round(gait.GAIT_PERIOD / robot.CONTROL_DT)
    k = 7
    phase = np.array([k / len(table)])
    feet = gait.foot_phases(phase)
    np.testing.assert_allclose(table[k, 0:2], [np.sin(2 * np.pi * phase[0]), np.cos(2 * np.pi * phase[0])])
    np.testing.assert_allclose(table[k, 2:4], gait.desired_contact(feet)[0])
    np.testing.assert_allclose(table[k, 4:6], gait.swing_height_target(feet)[0])
    targets = raibert_targets(feet, np.array([[1.0, 0.0, 0.0]]), stance_width=0.0)[0]
    np.testing.assert_allclose(table[k, 6:8], targets[:, 0])
    with pytest.raises(ValueError, match="whole number of control steps"):
        gait.cycle_table(0.03)


def _reference_terms(x: dict) -> np.ndarray:
    """Table 4 written term by term for one robot with scalar math, independently of `zerith1.rewards`."""
    c, v, w = x["command"][0], x["base_linvel"][0], x["base_angvel"][0]
    up, stance = x["base_up"][0], x["stance"][0]
    force = x["foot_force"][0].reshape(2, 3)
    speed = x["foot_speed_xy"][0].reshape(2, 2)
    a, a1, a2 = x["action"][0], x["last_action"][0], x["last_last_action"][0]
    tilt = np.arccos(x["foot_up_z"][0])
    terms = {
        "alive": 1.0,
        "lin_vel_tracking": np.exp(-5 * np.sum((v[:2] - c[:2]) ** 2)),
        "yaw_vel_tracking": np.exp(-5 * (w[2] - c[2]) ** 2),
        "swing_force": sum((1 - stance[f]) * np.exp(-np.sum(force[f] ** 2) / 100) for f in range(2)),
        "stance_velocity": sum(stance[f] * np.exp(-np.sum(speed[f] ** 2) / 5) for f in range(2)),
        "raibert_placement": np.sum(x["raibert_error"][0] ** 2),
        "swing_height": sum((1 - stance[f]) * x["swing_height_error"][0, f] ** 2 for f in range(2)),
        "body_height": np.exp(-1000 * x["height_error"][0] ** 2),
        "z_velocity": (up @ v) ** 2,
        "foot_slip": sum(x["foot_contact"][0, f] * np.sum(speed[f] ** 2) for f in range(2)),
        "hip_position": np.exp(-100 * np.sum(x["hip_roll_yaw"][0] ** 2)),
        "feet_orientation": np.exp(-10 * tilt.sum()),
        "feet_stumble": float(any(np.hypot(*force[f, :2]) > 4 * abs(force[f, 2]) for f in range(2))),
        "orientation": np.exp(-10 * np.sum(up[:2] ** 2)),
        "leg_collision": float(x["leg_collision"][0]),
        "joint_limit": float(x["outside_limits"][0]),
        "torques": np.sum(x["torques"][0] ** 2),
        "joint_velocities": np.sum(x["joint_vel"][0] ** 2),
        "joint_accelerations": np.sum(x["joint_acc"][0] ** 2),
        "action_rate": np.linalg.norm(a),
        "action_smoothing": np.sum((a1 - a) ** 2),
        "action_smoothing_2": np.sum((a2 - 2 * a1 + a) ** 2),
    }
    return np.array([terms[name] for name in REWARD_NAMES])


def _random_inputs(rng: np.random.Generator, n: int) -> dict[str, np.ndarray]:
    up = rng.normal(size=(n, 3)) + np.array([0.0, 0.0, 4.0])
    return {
        "command": rng.uniform(-1, 1, (n, 3)),
        "base_linvel": rng.normal(size=(n, 3)),
        "base_angvel": rng.normal(size=(n, 3)),
        "base_up": up / np.linalg.norm(up, axis=1, keepdims=True),
        "height_error": rng.normal(scale=0.05, size=n),
        "joint_vel": rng.normal(size=(n, 12)),
        "joint_acc": rng.normal(scale=50, size=(n, 12)),
        "torques": rng.normal(scale=20, size=(n, 12)),
        "outside_limits": rng.random(n) < 0.5,
        "hip_roll_yaw": rng.normal(scale=0.1, size=(n, 4)),
        "foot_up_z": rng.uniform(0.8, 1.0, size=(n, 2)),
        "foot_speed_xy": rng.normal(size=(n, 4)),
        "foot_force": rng.normal(scale=20, size=(n, 6)),
        "foot_contact": rng.random((n, 2)) < 0.5,
        "swing_height_error": rng.normal(scale=0.05, size=(n, 2)),
        "raibert_error": rng.normal(scale=0.1, size=(n, 4)),
        "stance": rng.random((n, 2)),
        "leg_collision": rng.random(n) < 0.5,
        "action": rng.uniform(-1, 1, (n, 12)),
        "last_action": rng.uniform(-1, 1, (n, 12)),
        "last_last_action": rng.uniform(-1, 1, (n, 12)),
    }


@pytest.mark.parametrize("seed", range(5))
def test_named_reward_terms_match_a_scalar_reference(seed):
    x = _random_inputs(np.random.default_rng(seed), 1)
    np.testing.assert_allclose(
        reward_terms_by_name(RewardInputs(**x))[0], _reference_terms(x), rtol=1e-10, atol=1e-12
    )
    assert list(TERMS) == list(REWARD_NAMES) and all(TERMS[name].__doc__ for name in REWARD_NAMES)


@pytest.mark.parametrize("seed", range(3))
def test_fused_reward_terms_match_the_named_terms(seed):
    rng = np.random.default_rng(seed)
    x = RewardInputs(**_random_inputs(rng, 64))
    np.testing.assert_allclose(reward_terms(x), reward_terms_by_name(x), rtol=1e-10, atol=1e-12)
    # Edge cases: exact stance / swing, contacts everywhere, stumbles just either side of the force ratio
    force = x.foot_force.copy()
    force[:16, 2] = np.hypot(force[:16, 0], force[:16, 1]) / 4.0 * np.repeat([1 - 1e-9, 1 + 1e-9], 8)
    force[:16, 5] = 1e3  # the right foot firmly on the ground
    edge = x._replace(stance=np.round(x.stance), foot_contact=np.ones_like(x.foot_contact), foot_force=force)
    np.testing.assert_allclose(reward_terms(edge), reward_terms_by_name(edge), rtol=1e-10, atol=1e-12)
    stumble = reward_terms(edge)[:16, REWARD_NAMES.index("feet_stumble")]
    assert stumble[:8].all() and not stumble[8:].any()


def test_reward_weights_follow_table_4():
    assert len(REWARD_NAMES) == 22
    assert (
        DEFAULT_REWARD_WEIGHTS["stance_velocity"] == 10.0
        and DEFAULT_REWARD_WEIGHTS["raibert_placement"] == -30.0
    )
    assert DEFAULT_REWARD_WEIGHTS["joint_accelerations"] == -2.5e-7 and DEFAULT_REWARD_WEIGHTS["alive"] == 0.5


@pytest.mark.parametrize(
    ("delay_s", "expected"),
    [(0.0, [0, 0, 0, 0]), (0.005, [1, 0, 0, 0]), (0.015, [1, 1, 1, 0]), (0.02, [1, 1, 1, 1]),
     (0.025, [2, 1, 1, 1]), (0.04, [2, 2, 2, 2])],
)  # fmt: skip
def test_delay_lags(delay_s, expected):
    # Sub-step j applies the latest action sent at or before time j - delay (in sub-steps; 4 per action).
    lags = delay_lags(np.array([[delay_s]]), physics_dt=0.005, decimation=4)
    np.testing.assert_array_equal(lags[0], expected)


def test_sudden_schedule_gives_short_impulses_every_two_seconds():
    draw, on = schedule_table(SCENARIOS["sudden-centroid"].force, 1000)
    np.testing.assert_array_equal(np.flatnonzero(draw), np.arange(100, 1000, 100))
    np.testing.assert_array_equal(
        np.flatnonzero(on), [s + k for s in range(100, 1000, 100) for k in range(5)]
    )
    draw, on = schedule_table(SCENARIOS["continuous-feet"].force, 20)
    assert on.all() and np.array_equal(np.flatnonzero(draw), [0, 5, 10, 15])
    with pytest.raises(ValueError, match="target must be one of"):
        ForceSchedule("head", (0, 1))


def test_sudden_impulses_reach_the_env_on_schedule():
    schedule = SCENARIOS["sudden-hands"].force
    env = Zerith1Env(scenario=Scenario("standing, sudden hands", NOMINAL, schedule), command=(0, 0, 0))
    env.reset(seed=0)
    magnitudes = []
    for _ in range(106):
        magnitudes.append(np.linalg.norm(env.step(np.zeros(12))[4]["external_force"]))
    hands = [env.model.body(name).id for name in robot.HAND_BODIES]
    magnitudes = np.array(magnitudes)
    assert magnitudes[:100].max() == 0 and magnitudes[105] == 0
    assert np.all((magnitudes[100:105] >= 150) & (magnitudes[100:105] <= 200))
    assert np.all(env.data.xfrc_applied[hands] == 0.0)


def test_horizontal_vectors_and_commands_cover_their_ranges():
    u = np.random.default_rng(0).random((2000, 4))
    vectors = horizontal_vectors(u[:, :2], (150.0, 200.0))
    norms = np.linalg.norm(vectors, axis=1)
    assert norms.min() >= 150 and norms.max() <= 200 and np.all(vectors[:, 2] == 0)
    assert np.ptp(np.arctan2(vectors[:, 1], vectors[:, 0])) > 6.0
    ranges = CommandRanges()
    commands = commands_from_uniforms(u, *command_bounds(ranges), ranges.standing_probability)
    standing = np.all(commands == 0, axis=1)
    assert 0.05 < standing.mean() < 0.15
    assert commands[:, 0].min() >= 0 and commands[:, 0].max() <= 0.7 and commands[~standing, 0].max() > 0.65


def test_terrain_height_lookup_is_bilinear_on_the_grid():
    terrain = Terrain(UNEVEN, seed=3)
    h, res, half = terrain.heights, UNEVEN.resolution, UNEVEN.half_size
    r, c = 40, 71
    corner = np.array([c * res - half, r * res - half])
    assert terrain.height_at(corner)[()] == pytest.approx(h[r, c])
    middle = corner + res / 2
    assert terrain.height_at(middle)[()] == pytest.approx(h[r : r + 2, c : c + 2].mean())
    assert h.max() == pytest.approx(UNEVEN.max_height) and h.min() == 0.0


def test_observation_layouts_are_consistent():
    assert sum(size for _, size in POLICY_LAYOUT) == 46
    slices = layout_slices(CRITIC_LAYOUT)
    assert slices["policy_noiseless"] == slice(0, 46)
    assert list(slices)[-1] == "domain_action_delay" and slices["domain_action_delay"].stop == CRITIC_SIZE
