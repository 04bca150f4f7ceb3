"""The robust recipe's parts: the critic's known input scales, forces taking turns between targets, the
`robust` scenario and its preset (hyperparams/huri_robust.yml)."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from stable_baselines3.common.vec_env import VecNormalize

import zerith_gym
from sb3_huri import HuRiPPO
from sb3_huri.zoo import algorithm_kwargs, normalize_kwargs, read_preset
from zerith_gym.core.disturbances import (
    FORCE_TARGET_NAMES,
    TARGET_INDEX,
    ForceCycle,
    ForceSchedule,
    horizontal_vectors,
)
from zerith_gym.core.observations import layout_slices
from zerith_gym.core.randomization import NOMINAL, WIDEST, domain_bounds
from zerith_gym.core.scenarios import SCENARIOS, scaled_scenario
from zerith_gym.zerith1.constants import ZERITH1
from zerith_gym.zerith1.observations import CRITIC_LAYOUT, CRITIC_SCALE, critic_in_units

ROBUST_PRESET = Path(__file__).resolve().parent.parent / "hyperparams" / "huri_robust.yml"
CRITIC = layout_slices(CRITIC_LAYOUT)
DOMAIN = slice(CRITIC["domain_friction"].start, CRITIC["domain_action_delay"].stop)


@pytest.mark.parametrize("name", list(SCENARIOS))
def test_no_critic_input_saturates_in_any_scenario(name):
    """Domain parameters and the external force stay in [-1, 1] at every scenario's full ranges (the test
    ranges included), and no critic input reaches 10 (VecNormalize's clip) while robots stumble and fall under
    random actions: contact forces at touchdowns reach about 6 body weights, the others stay within 3."""
    env = zerith_gym.make_vec_env(8, seed=0, scenario=name, workers=0)
    rng = np.random.default_rng(0)
    obs, largest = env.reset(), 0.0
    for _ in range(150):
        obs, *_ = env.step(rng.normal(scale=0.1, size=(8, 12)))
        critic = obs["critic"]
        assert np.isfinite(critic).all()
        assert np.abs(critic[:, DOMAIN]).max() <= 1.0 + 1e-6
        assert np.abs(critic[:, CRITIC["external_force"]]).max() <= 1.0 + 1e-6
        largest = max(largest, float(np.abs(critic).max()))
    env.close()
    assert largest < 10.0


def test_critic_scales_map_the_widest_domain_ranges_onto_minus_one_to_one():
    low, high = domain_bounds(WIDEST)
    ends = np.stack([np.full(CRITIC_SCALE.size, -1.0), np.full(CRITIC_SCALE.size, 1.0)])
    np.testing.assert_allclose(critic_in_units(ends)[:, DOMAIN], np.stack([low, high]), rtol=1e-6, atol=1e-7)
    assert CRITIC_SCALE[CRITIC["external_force"]] == pytest.approx(1 / 200)


def test_a_force_cycle_takes_turns_between_its_schedules():
    continuous = ForceSchedule("hands", (0.0, 100.0), period_steps=5, duration_steps=5)
    sudden = ForceSchedule("feet", (150.0, 200.0), period_steps=100, duration_steps=5, start_step=100)
    table = ForceCycle((continuous, sudden), phase_steps=100).table(400)
    steps = np.arange(400)
    in_sudden = (steps // 100) % 2 == 1
    targets = np.where(in_sudden, TARGET_INDEX["feet"], TARGET_INDEX["hands"])
    np.testing.assert_array_equal(table.target, targets)
    np.testing.assert_array_equal(table.draw, np.where(in_sudden, steps % 100 == 0, steps % 5 == 0))
    np.testing.assert_array_equal(table.on, np.where(in_sudden, steps % 100 < 5, True))
    np.testing.assert_array_equal(table.magnitude[:, 1], np.where(in_sudden, 200.0, 100.0))
    # A phase that starts within its schedule's period draws a force of its own at its first step.
    slow = ForceSchedule("hands", (0.0, 10.0), period_steps=30, duration_steps=30)
    table = ForceCycle((continuous, slow), phase_steps=100).table(300)
    assert table.draw[100] and table.target[100] == TARGET_INDEX["hands"] and table.magnitude[100, 1] == 10.0
    assert table.draw[200] and not table.draw[101:120].any()
    with pytest.raises(ValueError, match="phase_steps must be a positive integer"):
        ForceCycle((continuous,), phase_steps=0)
    with pytest.raises(ValueError, match="one or more ForceSchedule"):
        ForceCycle(())
    for phases in ((), (2,), (0, -1)):
        with pytest.raises(ValueError, match=r"start_phases must be one or more phase indices in \[0, 2\)"):
            ForceCycle((continuous, sudden), start_phases=phases)


def test_robust_episodes_start_with_each_target_alike_and_the_first_impulse_at_two_seconds():
    """`robust` starts each episode at the continuous phase of a target drawn at random; the draw takes a
    reset uniform nothing else reads, so it is the same per seed and on both backends' task functions."""
    gentle = scaled_scenario(SCENARIOS["robust"], 0.2)
    n = 60
    env = zerith_gym.make_vec_env(n, seed=3, scenario=gentle, workers=0)
    env.reset()
    task = env.robots.task
    offsets = task.state.force_offset.copy()
    counts = {offset: int(np.sum(offsets == offset)) for offset in (0, 200, 400)}
    assert sum(counts.values()) == n and min(counts.values()) >= 10, counts
    table = gentle.force.table(2000)
    first_targets = table.target[offsets]
    np.testing.assert_array_equal(first_targets, offsets // 200)  # centroid, hands, feet: TARGET_INDEX order
    first_impulse = np.full(n, -1)
    for step in range(120):
        _, _, dones, infos = env.step(np.zeros((n, 12)))
        assert not dones.any()  # at scale 0.2 a standing robot stays up this long
        big = np.linalg.norm([info["external_force"] for info in infos], axis=1) > 0.2 * 150 - 1e-6
        first_impulse = np.where((first_impulse < 0) & big, step, first_impulse)
    np.testing.assert_array_equal(first_impulse, 100)
    again = zerith_gym.make_vec_env(n, seed=3, scenario=gentle, workers=0)
    again.reset()
    np.testing.assert_array_equal(again.robots.task.state.force_offset, offsets)
    env.close(), again.close()

    one_start = replace(gentle, force=replace(gentle.force, start_phases=(0,)))
    plain = zerith_gym.make_vec_env(4, seed=3, scenario=one_start, workers=0)
    plain.reset()
    assert not plain.robots.task.state.force_offset.any()
    plain.close()
    late = replace(gentle, force=replace(gentle.force, start_phases=(5,)))
    with pytest.raises(ValueError, match="starts episodes 500 steps into its force cycle"):
        zerith_gym.make_vec_env(1, scenario=late, episode_steps=500, workers=0)


def test_robust_forces_act_on_the_bodies_of_the_current_target_only():
    """Each step, the force of `info["external_force"]` acts on each body of the scheduled target and on
    no other body, robot by robot (their episodes are at different steps after falls)."""
    gentle = scaled_scenario(SCENARIOS["robust"], 0.2)  # robots with zero actions stand through it
    env = zerith_gym.make_vec_env(4, seed=0, scenario=gentle, workers=0)
    table = gentle.force.table(2000)
    sim = env.robots.sim
    bodies = {
        target: [sim.models[0].body(b).id for b in names] for target, names in ZERITH1.force_bodies.items()
    }
    env.reset()
    seen = set()
    for _ in range(520):  # every target's phases come within 400 steps of any start phase
        state = env.robots.task.state
        step_count = state.step_count + state.force_offset  # the table step about to be simulated
        _, _, _, infos = env.step(np.zeros((4, 12)))
        for i, info in enumerate(infos):
            target = FORCE_TARGET_NAMES[table.target[step_count[i]]]
            applied = sim.datas[i].xfrc_applied[:, :3]
            if info["fall"] or info.get("TimeLimit.truncated"):
                continue  # reset after the step
            for name, ids in bodies.items():
                expected = info["external_force"] if name == target else np.zeros(3)
                np.testing.assert_allclose(applied[ids], np.broadcast_to(expected, (len(ids), 3)))
            if np.any(info["external_force"]):
                seen.add(target)
    env.close()
    assert seen == set(FORCE_TARGET_NAMES)


def test_the_robust_preset_trains_with_its_curriculum_and_normalizer():
    preset = read_preset("Zerith1-v0", ROBUST_PRESET)
    env_kwargs = dict(preset["env_kwargs"])
    assert env_kwargs.pop("scenario") == "robust"
    env = VecNormalize(zerith_gym.make_vec_env(4, seed=0, scenario="robust", workers=0, **env_kwargs),
                       **normalize_kwargs(preset))  # fmt: skip
    kwargs = {**algorithm_kwargs(preset), "n_steps": 16, "n_epochs": 1}
    model = HuRiPPO(preset["policy"], env, seed=0, **kwargs)
    model.learn(128)
    assert env.norm_obs_keys == ["policy"] and "critic" not in env.obs_rms
    groups = {group["name"]: group["lr"] for group in model.policy.optimizer.param_groups}
    assert groups["critic"] == pytest.approx(3e-4)
    assert groups["actor"] == pytest.approx(model.kl_learning_rate)
    env.close()


def test_scaling_the_robust_scenario_scales_every_force_of_its_cycle():
    half = scaled_scenario(SCENARIOS["robust"], 0.5)
    assert half.force.magnitude == (0.0, 100.0)
    continuous, sudden = (0.0, 50.0), (75.0, 100.0)
    assert [s.magnitude for s in half.force.schedules] == [continuous, sudden] * 3 + [continuous]


def test_robust_gives_the_continuous_feet_force_twice_the_time_of_each_other_force():
    """Per 14-s cycle: two 2-s phases of continuous force on the feet, re-drawn every 0.1 s, and one of each
    other force (the feet's continuous force topples the agent most; docs/history/training.md)."""
    cycle = SCENARIOS["robust"].force
    table = cycle.table(7 * cycle.phase_steps)
    continuous = table.magnitude[:, 1] == 100.0
    for target, index in TARGET_INDEX.items():
        steps = {"continuous": np.sum((table.target == index) & continuous),
                 "sudden": np.sum((table.target == index) & ~continuous)}  # fmt: skip
        assert steps == {"continuous": 200 if target == "feet" else 100, "sudden": 100}, target
    held = np.flatnonzero((table.target == TARGET_INDEX["feet"]) & continuous)
    np.testing.assert_array_equal(held, np.r_[400:500, 600:700])
    assert table.on[held].all()
    np.testing.assert_array_equal(np.flatnonzero(table.draw[held]), np.arange(0, 200, 5))


def test_the_side_impact_is_one_200_newton_push_from_the_side_at_two_seconds():
    standing = replace(SCENARIOS["side-impact"], randomization=NOMINAL)  # zero actions stand through it
    env = zerith_gym.make_vec_env(2, seed=0, scenario=standing, workers=0)
    env.reset()
    forces = []
    for _ in range(110):
        _, _, dones, infos = env.step(np.zeros((2, 12)))
        assert not dones.any()
        forces.append(infos[0]["external_force"])
    forces = np.array(forces)
    pushed = np.flatnonzero(np.linalg.norm(forces, axis=1))
    np.testing.assert_array_equal(pushed, np.arange(100, 105))
    np.testing.assert_allclose(forces[pushed], np.tile([0.0, 200.0, 0.0], (5, 1)), atol=1e-9)
    env.close()
    random_direction = horizontal_vectors(np.array([[0.0, 0.25]]), np.array([1.0, 1.0]), np.array([np.nan]))
    np.testing.assert_allclose(random_direction, [[0.0, 1.0, 0.0]], atol=1e-12)  # NaN: the uniform draw


def test_robust_commands_straddle_the_test_command():
    """The test's 1 m/s must lie inside the forward speeds the recipe trains on, not at their edge."""
    env = zerith_gym.Zerith1Env(scenario="robust")
    forward = np.array([env.reset(seed=seed)[1]["command"][0] for seed in range(60)])
    moving = forward[forward != 0.0]
    assert (moving > 1.0).sum() >= 5 and (moving < 1.0).sum() >= 30
    assert moving.min() >= 0.0 and moving.max() <= 1.3
