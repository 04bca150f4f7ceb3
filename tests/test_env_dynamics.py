"""Zerith1-v0 physics: robot spec, stability, disturbances, randomization ranges, every scenario, a soak."""

from __future__ import annotations

from dataclasses import replace

import mujoco
import numpy as np
import pytest

from zerith_gym import SCENARIOS, Zerith1Env
from zerith_gym.core.disturbances import ForceSchedule
from zerith_gym.core.observations import layout_slices
from zerith_gym.core.randomization import NOMINAL, TRAIN
from zerith_gym.core.scenarios import Scenario
from zerith_gym.core.spec import sensor_slices
from zerith_gym.zerith1 import constants as robot
from zerith_gym.zerith1.observations import CRITIC_LAYOUT, critic_in_units

CRITIC = layout_slices(CRITIC_LAYOUT)


def test_robot_mass_joints_and_actuators_match_the_spec():
    env = Zerith1Env(scenario="nominal")
    model = env.model
    assert model.body_subtreemass[model.body(robot.ROOT_BODY).id] == pytest.approx(robot.TOTAL_MASS, abs=0.5)
    assert 34.0 <= robot.TOTAL_MASS <= 38.0
    names = [mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_ACTUATOR, i) for i in range(model.nu)]
    assert tuple(names) == robot.JOINT_NAMES
    np.testing.assert_allclose(model.actuator_gainprm[:, 0], robot.KP)
    np.testing.assert_allclose(-model.actuator_biasprm[:, 2], robot.KD)
    np.testing.assert_allclose(model.actuator_forcerange[:, 1], robot.TORQUE_LIMIT)
    assert model.opt.timestep == robot.PHYSICS_DT
    assert abs(robot.DECIMATION * robot.PHYSICS_DT - robot.CONTROL_DT) < 1e-12
    for body in (*robot.HAND_BODIES, *robot.FOOT_BODIES):
        assert model.body(body).id > 0


def test_default_stance_holds_5_seconds_with_zero_action():
    env = Zerith1Env(scenario="nominal", command=(0.0, 0.0, 0.0))
    env.reset(seed=0)
    start = env.data.qpos[:2].copy()
    for _ in range(250):
        obs, _, terminated, truncated, info = env.step(np.zeros(12))
        assert not (terminated or truncated or info["fall"])
    assert env.data.qpos[2] > 0.7
    assert np.abs(obs["policy"][:2]).max() < 0.1  # roll, pitch
    assert np.linalg.norm(env.data.qpos[:2] - start) < 0.1


def test_legs_colliding_with_each_other_are_detected():
    env = Zerith1Env(scenario="nominal")
    env.reset(seed=0)
    model, data = env.model, env.data
    sensor = sensor_slices(model)["leg_collision"]
    assert data.sensordata[sensor][0] == 0
    data.qpos[7 + 1], data.qpos[7 + 7] = -0.5, 0.5  # hips rolled inwards: the legs cross
    mujoco.mj_forward(model, data)
    assert data.sensordata[sensor][0] > 0
    pairs = {
        tuple(sorted((model.geom(c.geom1).name, model.geom(c.geom2).name))) for c in data.contact[: data.ncon]
    }
    assert any(a.startswith("left") and b.startswith("right") for a, b in pairs)
    # Only the feet touch the ground; geoms of the same leg never collide with each other.
    assert all(a == "floor" and b.endswith("foot") for a, b in pairs if "floor" in (a, b))
    assert not any(a.split("_")[0] == b.split("_")[0] for a, b in pairs if "floor" not in (a, b))


def _displacement(scenario: Scenario, steps: int) -> tuple[np.ndarray, list]:
    env = Zerith1Env(scenario=scenario, command=(0.0, 0.0, 0.0))
    env.reset(seed=4)
    start = env.data.qpos[:2].copy()
    forces = []
    for _ in range(steps):
        _, _, terminated, _, info = env.step(np.zeros(12))
        forces.append(info["external_force"])
        if terminated:
            break
    return env.data.qpos[:2] - start, forces


def test_centroid_push_moves_the_robot_along_the_force():
    push = ForceSchedule("centroid", (150.0, 150.0), period_steps=1000, duration_steps=5, start_step=20)
    still, _ = _displacement(Scenario("calm", NOMINAL), 60)
    pushed, forces = _displacement(Scenario("push", NOMINAL, push), 60)
    force = forces[20]
    assert np.linalg.norm(force) == pytest.approx(150.0) and force[2] == 0.0
    assert not np.any(forces[19]) and not np.any(forces[25])
    direction = force[:2] / np.linalg.norm(force[:2])
    assert np.linalg.norm(still) < 0.05
    assert (pushed - still) @ direction > 0.1


@pytest.mark.parametrize("name", list(SCENARIOS))
def test_every_scenario_builds_and_runs(name):
    env = Zerith1Env(scenario=name)
    obs, _ = env.reset(seed=0)
    rng = np.random.default_rng(0)
    forces = np.full(120, np.nan)  # force magnitude by step of the first episode
    episode_step, episodes = 0, 0
    for _ in range(240):
        obs, reward, terminated, truncated, info = env.step(rng.uniform(-0.2, 0.2, 12))
        assert np.isfinite(obs["policy"]).all() and np.isfinite(obs["critic"]).all() and np.isfinite(reward)
        assert not info["sim_unstable"]
        if episodes == 0 and episode_step < len(forces):
            forces[episode_step] = np.linalg.norm(info["external_force"])
        episode_step += 1
        if terminated or truncated:
            env.reset()
            episode_step, episodes = 0, episodes + 1
    scenario = SCENARIOS[name]
    forces = forces[~np.isnan(forces)]
    assert forces.max() <= scenario.force.magnitude[1] + 1e-9
    if name.startswith("continuous") or name in ("load", "friction", "load-friction"):
        assert forces.max() > 10.0
    if name.startswith("sudden") and len(forces) >= 110:  # impulses at 2 s, 4 s, ... lasting 0.1 s
        assert forces[:100].max() == 0.0 and forces[100:105].min() >= 150.0 and forces[105:].max() == 0.0
    if name in ("nominal", "uneven"):
        assert forces.max() == 0.0


def test_uneven_terrain_is_under_the_robot():
    env = Zerith1Env(scenario="uneven")
    obs, _ = env.reset(seed=0)
    terrain = env.terrain
    assert not terrain.is_plane and terrain.heights.max() == pytest.approx(terrain.spec.max_height)
    base = env.data.qpos[:2]
    assert terrain.height_at(base[None])[0] >= 0.0
    samples = critic_in_units(obs["critic"])[CRITIC["foot_height_samples"]]
    assert samples.std() > 1e-3  # the ground around the feet is not flat


def test_randomization_stays_in_its_ranges_and_reaches_the_critic():
    env = Zerith1Env(scenario="train")
    nominal = env.nominal
    root, links = nominal.root, nominal.links
    frictions, masses = [], []
    for seed in range(40):
        obs, _ = env.reset(seed=seed)
        m = env.model
        friction = m.geom_friction[nominal.friction_geoms, 0]
        assert np.all(friction == friction[0])
        added = m.body_mass[root] - nominal.body_mass[root]
        assert TRAIN.added_mass[0] <= added <= TRAIN.added_mass[1]
        offset = m.body_ipos[root] - nominal.body_ipos[root]
        assert np.all((offset >= TRAIN.com_offset[0]) & (offset <= TRAIN.com_offset[1]))
        scale = m.body_mass[links] / nominal.body_mass[links]
        assert np.all((scale >= 0.8 - 1e-12) & (scale <= 1.4 + 1e-12))
        kp = m.actuator_gainprm[:, 0] / nominal.gain
        kd = -m.actuator_biasprm[:, 2] / nominal.damping
        strength = m.actuator_forcerange[:, 1] / nominal.forcerange[:, 1]
        assert np.all((strength >= 0.9 - 1e-12) & (strength <= 1.1 + 1e-12))
        assert np.all((kp / strength >= 0.85 - 1e-9) & (kp / strength <= 1.15 + 1e-9))
        assert np.all((kd / strength >= 0.85 - 1e-9) & (kd / strength <= 1.15 + 1e-9))
        np.testing.assert_allclose(-m.actuator_biasprm[:, 1], m.actuator_gainprm[:, 0])
        joints = env.data.qpos[7:]
        ratio = joints[robot.DEFAULT_JOINT_POS != 0] / robot.DEFAULT_JOINT_POS[robot.DEFAULT_JOINT_POS != 0]
        assert np.all((ratio >= 0.5) & (ratio <= 1.5))
        critic = critic_in_units(obs["critic"].astype(np.float64))
        sole = critic[CRITIC["domain_friction"]][0]  # the drawn material; contacts slide at its mean with 1
        assert TRAIN.friction[0] <= sole <= TRAIN.friction[1]
        assert friction[0] == pytest.approx((sole + 1.0) / 2.0, rel=1e-6)
        assert critic[CRITIC["domain_added_mass"]][0] == pytest.approx(added, rel=1e-5, abs=1e-6)
        np.testing.assert_allclose(critic[CRITIC["domain_link_mass_scale"]], scale, rtol=1e-6)
        delay = critic[CRITIC["domain_action_delay"]][0]
        assert 0.0 <= delay <= 0.04
        frictions.append(friction[0])
        masses.append(added)
    assert np.ptp(frictions) > 0.5 and np.ptp(masses) > 2.0  # values actually vary between episodes


def test_nominal_scenario_has_no_randomization():
    env = Zerith1Env(scenario="nominal")
    first, _ = env.reset(seed=0)
    second, _ = env.reset(seed=1)
    np.testing.assert_array_equal(first["critic"][CRITIC["domain_friction"].start :],
                                  second["critic"][CRITIC["domain_friction"].start :])  # fmt: skip
    np.testing.assert_array_equal(env.model.body_mass, env.nominal.body_mass)


def test_random_action_soak_stays_finite():
    env = Zerith1Env(scenario="train")
    env.reset(seed=0)
    rng = np.random.default_rng(0)
    episodes = 0
    for _ in range(10_000):
        obs, reward, terminated, truncated, info = env.step(rng.uniform(-1.0, 1.0, 12))
        assert np.isfinite(reward) and np.isfinite(obs["critic"]).all() and np.isfinite(obs["policy"]).all()
        assert not info["sim_unstable"]
        if terminated or truncated:
            assert all(np.isfinite(v) for v in info["episode_terms"].values())
            episodes += 1
            env.reset()
    assert episodes > 10  # random actions make it fall: resets are exercised too


def test_a_sole_slides_at_the_mean_of_its_material_and_the_grounds():
    """The drawn friction is the sole's material; MuJoCo's contacts between a sole and the ground must get
    the mean of that and the ground's 1 (PhysX's default rule, which the paper trained under)."""
    env = Zerith1Env(scenario=Scenario("low-friction", replace(NOMINAL, friction=(0.1, 0.1))))
    env.reset(seed=0)
    for _ in range(10):
        env.step(np.zeros(12))
    soles = set(env.nominal.sole_geoms.tolist())
    contacts = env.data.contact[: env.data.ncon]
    on_soles = [c.friction[0] for c in contacts if c.geom1 in soles or c.geom2 in soles]
    assert on_soles, "the robot should stand on its soles"
    np.testing.assert_allclose(on_soles, 0.55, rtol=1e-9)
