"""The MJX backend (`make_vec_env(n, backend="mjx")`) against the CPU backend, with JAX on the CPU.

The task code is shared (zerith_gym.core.task over numpy or jax.numpy), so these tests hold the two backends
to each other: the task functions on the same inputs, the physics from the same start, the randomized
parameters' distributions, and the training pipelines (SB3 PPO, HuRiPPO, RL Zoo) on the MJX env.
"""

from __future__ import annotations

import os
import subprocess
import sys

import numpy as np
import pytest
from scipy import stats

jax = pytest.importorskip("jax")
pytest.importorskip("mujoco.mjx")
import jax.numpy as jnp  # noqa: E402

import zerith_gym  # noqa: E402
from zerith_gym.core.observations import layout_slices  # noqa: E402
from zerith_gym.core.physics import NominalModel, build_model, domain_model_fields  # noqa: E402
from zerith_gym.core.randomization import DOMAIN_VECTOR_SIZE, DomainParams  # noqa: E402
from zerith_gym.core.scenarios import SCENARIOS  # noqa: E402
from zerith_gym.core.spec import read_sensors  # noqa: E402
from zerith_gym.core.task import reset_values, scenario_arrays, step_disturbances, task_constants  # noqa: E402
from zerith_gym.terrain.ground import Terrain  # noqa: E402
from zerith_gym.terrain.levels import TerrainLevels  # noqa: E402
from zerith_gym.zerith1 import constants as robot  # noqa: E402
from zerith_gym.zerith1.observations import CRITIC_LAYOUT, POLICY_LAYOUT  # noqa: E402
from zerith_gym.zerith1.task import HUMANOID_DRAWS, HUMANOID_TASK, RESET_DRAWS, STEP_DRAWS, judge_step  # noqa: E402

COMMAND = (0.5, 0.0, 0.0)


def _to_jax(tree):
    return jax.tree.map(lambda x: jnp.asarray(x) if isinstance(x, np.ndarray) else x, tree)


def _assert_tree_close(numpy_tree, jax_tree, rtol=2e-5, atol=2e-5):
    for a, b in zip(jax.tree.leaves(numpy_tree), jax.tree.leaves(jax_tree), strict=True):
        np.testing.assert_allclose(
            np.asarray(b, dtype=float), np.asarray(a, dtype=float), rtol=rtol, atol=atol
        )


@pytest.mark.parametrize("scenario", ["train", "uneven", "multi-terrain", "robust"])
def test_task_functions_give_the_same_numbers_on_numpy_and_jax(scenario):
    """One definition of the task: the same functions on numpy (float64) and traced by jax (float32)."""
    rng = np.random.default_rng(0)
    n, sc = 16, SCENARIOS[scenario]
    terrain = Terrain(sc.terrain)
    model = build_model(terrain, robot.ZERITH1)
    arrays = scenario_arrays(sc, None, 1000, HUMANOID_TASK)
    reset_u, step_u = rng.random((n, RESET_DRAWS)), rng.random((n, STEP_DRAWS))
    spawn = TerrainLevels(terrain.spec, np.arange(n), robot.CONTROL_DT).spawn_points(np.arange(n))
    jitter = terrain.spec.spawn_jitter
    jitted_reset = jax.jit(lambda u, a, xy: reset_values(u, a, xy, jitter, robot.ZERITH1, HUMANOID_DRAWS))
    _assert_tree_close(
        reset_values(reset_u, arrays, spawn, jitter, robot.ZERITH1, HUMANOID_DRAWS),
        jitted_reset(_to_jax(reset_u), _to_jax(arrays), jnp.asarray(spawn)),
    )

    step_count = rng.integers(0, 1000, n)
    force_offset = rng.choice(arrays.force_offsets, n)
    force, command = rng.normal(size=(n, 3)), rng.normal(size=(n, 3))
    args = (step_u, step_count, force_offset, force, command, arrays)
    disturbances = jax.jit(lambda *a: step_disturbances(*a, HUMANOID_DRAWS))
    _assert_tree_close(step_disturbances(*args, HUMANOID_DRAWS), disturbances(*_to_jax(args)))

    vector = reset_values(reset_u, arrays, spawn, jitter, robot.ZERITH1, HUMANOID_DRAWS).domain_vector
    nominal = NominalModel.capture(model, terrain, robot.ZERITH1)

    def fields(vector):
        return domain_model_fields(nominal, DomainParams.from_vector(vector))

    _assert_tree_close(fields(vector), jax.jit(fields)(jnp.asarray(vector)))

    # Sensor readings of robots standing on the terrain, with noise on every quantity.
    layout = robot.ZERITH1.sensor_layout(model)
    sensordata = rng.normal(scale=0.3, size=(n, model.nsensordata))
    sensordata[:, layout.base_pos] += np.column_stack([spawn, np.full(n, 0.75)])
    sensordata[:, layout.foot_pos] += np.tile(np.column_stack([spawn, np.zeros(n)]), 2)
    sensordata[:, layout.foot_force] *= 100.0
    constants = task_constants(
        terrain, np.array([model.joint(j).range for j in robot.JOINT_NAMES]), np.ones(22), 1000, HUMANOID_TASK
    )
    inputs = (
        rng.integers(0, 35, n),
        command,
        rng.uniform(-1, 1, (n, 3, 12)),
        rng.normal(size=(n, 12)),
        force,
        rng.normal(size=(n, DOMAIN_VECTOR_SIZE)),
        rng.normal(scale=0.1, size=(n, 46)),
    )

    def judged(sensordata, *inputs):
        return judge_step(read_sensors(layout, sensordata), *inputs, constants)

    _assert_tree_close(
        judged(sensordata, *inputs), jax.jit(judged)(*_to_jax((sensordata, *inputs))), rtol=1e-4, atol=1e-4
    )


@pytest.fixture(scope="module")
def nominal_pair():
    """Four robots in `nominal` on each backend, shared by the tests that compare them: an MJX env compiles
    its reset and step once (minutes on a CPU), and `_restart` gives every test the same start."""
    kwargs = dict(scenario="nominal", command=COMMAND, episode_steps=1000)
    cpu = zerith_gym.make_vec_env(4, seed=0, backend="cpu", workers=0, **kwargs)
    mjx = zerith_gym.make_vec_env(4, seed=0, backend="mjx", **kwargs)
    yield cpu, mjx
    cpu.close()
    mjx.close()


def _restart(*envs):
    """Seed 0 and reset each env (`nominal` starts every robot alike on both backends)."""
    for env in envs:
        env.seed(0)
    return [env.reset() for env in envs]


FORCE_TOLERANCE = dict(atol=0.25, rtol=2e-3)
"""Contact forces: 0.25 N, or 0.2% of the force at a touchdown's impact (hundreds of N)."""


VELOCITY_TOLERANCE = {"base_angular_velocity": 0.02, "joint_velocity": 0.05}
"""Velocities (rad/s) in the policy's observation: they jump at a touchdown, and a contact a sub-step apart
between the backends shows there. Measured worst cases with the walking agent, on an x86_64 machine whose
other figures stay within the 5e-3 below: 0.005 (base) and 0.037 (joints) at a touchdown; these are 10%
and 3% of the training noise on those entries (0.2 and 1.5 rad/s)."""


def _assert_backends_agree(obs_cpu, obs_mjx, reward_cpu, reward_mjx):
    forces = np.r_[layout_slices(CRITIC_LAYOUT)["foot_contact_force"]]
    others = np.setdiff1d(np.arange(obs_cpu["critic"].shape[1]), forces)
    blocks = layout_slices(POLICY_LAYOUT)
    rest = np.ones(obs_cpu["policy"].shape[1], dtype=bool)
    for name, atol in VELOCITY_TOLERANCE.items():
        block = blocks[name]
        np.testing.assert_allclose(obs_mjx["policy"][:, block], obs_cpu["policy"][:, block], atol=atol)
        rest[block] = False
    np.testing.assert_allclose(obs_mjx["policy"][:, rest], obs_cpu["policy"][:, rest], atol=5e-3)
    np.testing.assert_allclose(obs_mjx["critic"][:, others], obs_cpu["critic"][:, others], atol=5e-3)
    np.testing.assert_allclose(obs_mjx["critic"][:, forces], obs_cpu["critic"][:, forces], **FORCE_TOLERANCE)
    np.testing.assert_allclose(reward_mjx, reward_cpu, atol=5e-4)


def test_mjx_follows_the_cpu_backend_from_the_same_start(nominal_pair):
    """Nominal, fixed command, both robots standing (zero actions) for 40 steps while the gait clock runs.

    Tolerances (measured worst cases x ~5): policy observations 5e-3, rewards 5e-4, critic observations
    5e-3 apart from the contact forces (0.25 N of about 200 N).
    """
    cpu, mjx = nominal_pair
    obs_cpu, obs_mjx = _restart(cpu, mjx)
    np.testing.assert_allclose(obs_mjx["policy"], obs_cpu["policy"], atol=1e-5)
    actions = np.zeros((cpu.num_envs, 12))
    for _ in range(40):
        obs_cpu, reward_cpu, done_cpu, _ = cpu.step(actions)
        obs_mjx, reward_mjx, done_mjx, info_mjx = mjx.step(actions)
        _assert_backends_agree(obs_cpu, obs_mjx, reward_cpu, reward_mjx)
        assert not done_cpu.any() and not done_mjx.any()
    assert set(info_mjx[0]) == set(cpu.step(actions)[3][0])
    terms = np.array(list(info_mjx[0]["reward_terms"].values()))
    assert terms.sum() == pytest.approx(reward_mjx[0], abs=1e-5)


def _walking_policy():
    """The shipped PPO agent's deterministic actions on raw observations."""
    import pickle
    from pathlib import Path

    from stable_baselines3 import PPO

    run = Path(__file__).resolve().parent.parent / "trained_agents" / "huri-baseline" / "Zerith1-v0_1"
    model = PPO.load(run / "Zerith1-v0.zip", device="cpu")
    with open(run / "Zerith1-v0" / "vecnormalize.pkl", "rb") as file:
        normalizer = pickle.load(file)
    return lambda obs: model.predict(normalizer.normalize_obs(obs), deterministic=True)[0]


@pytest.mark.parametrize("policy", ["random", "walking"])
def test_mjx_follows_the_cpu_backend_with_moving_legs(nominal_pair, policy):
    """Touchdowns, lift-offs and falls alike: the soles are spheres and the integrator is Euler.

    Four robots in `nominal` from the same start, driven by random actions of std 0.1 or by the shipped
    walking agent, for 100 control steps or until the first fall, which comes at the same step and to the
    same robots on both backends. (Box soles part at the first touchdown: MJX keeps the box corners within
    1 mm of the deepest, MuJoCo every penetrating corner. With `implicitfast`, the backends part when an
    actuator reaches its torque limit: C MuJoCo drops the clamped actuator's damping from the implicit
    step, MJX keeps it.)
    """
    cpu, mjx = nominal_pair
    n = cpu.num_envs
    rng = np.random.default_rng(0)
    act = _walking_policy() if policy == "walking" else lambda obs: rng.normal(scale=0.1, size=(n, 12))
    obs_cpu, _ = _restart(cpu, mjx)
    for step in range(100):
        actions = act(obs_cpu)
        obs_cpu, reward_cpu, done_cpu, _ = cpu.step(actions)
        obs_mjx, reward_mjx, done_mjx, _ = mjx.step(actions)
        np.testing.assert_array_equal(done_mjx, done_cpu, err_msg=f"step {step}")
        if done_cpu.any():
            assert policy == "random", f"the walking agent fell at step {step}"
            break
        _assert_backends_agree(obs_cpu, obs_mjx, reward_cpu, reward_mjx)
    else:
        assert policy == "walking", "random actions of std 0.1 were expected to topple a robot"


QUADRUPED_TOLERANCE = {
    "base_linear_velocity": 0.02,
    "projected_gravity": 0.02,
    "joint_position_offset": 0.05,
    "height_samples": 5e-3,
}
"""Policy blocks of the quadruped compared under random actions (measured worst cases over 60 steps, x ~3:
0.0075 m/s, 0.0048, 0.018 rad, 0.00055 m). Its velocities and contact forces part further at touchdowns
(joint velocities by up to 1.07 rad/s, a foot's contact flag a step apart): a point foot on a light leg
lands a sub-step earlier or later on one backend, which the rewards (within 5e-4) hardly see."""


def test_mjx_follows_the_cpu_backend_with_the_quadruped():
    """`Go2Like-v0` on both backends from the same start: its legged_gym observations (height samples
    included), rewards and falls, and its contact readings (four feet, base and leg contacts), which MJX
    computes from its contacts as it does Zerith-1's. Standing for 20 steps (landing from the reset), then
    60 of random actions."""
    from zerith_gym.go2like.task import POLICY_LAYOUT as QUAD_POLICY

    n = 3
    kwargs = dict(robot="go2like", scenario="nominal", command=(0.5, 0.0, 0.0), episode_steps=1000)
    cpu = zerith_gym.make_vec_env(n, seed=0, backend="cpu", workers=0, **kwargs)
    mjx = zerith_gym.make_vec_env(n, seed=0, backend="mjx", **kwargs)
    obs_cpu, obs_mjx = cpu.reset(), mjx.reset()
    np.testing.assert_allclose(obs_mjx["policy"], obs_cpu["policy"], atol=1e-4)
    np.testing.assert_allclose(obs_mjx["critic"], obs_cpu["critic"], atol=1e-3)
    blocks = layout_slices(QUAD_POLICY)
    rng = np.random.default_rng(0)
    for step in range(80):
        # Within [-1, 1]: a few draws beyond it (the quadruped's actions reach +-100) move one robot's
        # touchdown a step apart on the two backends at step 56, and legged_gym's feet-air-time reward pays
        # it then (0.009): contact timing amplifies float32 rounding, as on Zerith-1 (docs/gpu.md).
        actions = np.zeros((n, 12)) if step < 20 else rng.normal(scale=0.3, size=(n, 12)).clip(-1, 1)
        obs_cpu, reward_cpu, done_cpu, _ = cpu.step(actions)
        obs_mjx, reward_mjx, done_mjx, info_mjx = mjx.step(actions)
        np.testing.assert_array_equal(done_mjx, done_cpu, err_msg=f"step {step}")
        for name, atol in QUADRUPED_TOLERANCE.items():
            block = blocks[name]
            np.testing.assert_allclose(obs_mjx["policy"][:, block], obs_cpu["policy"][:, block], atol=atol)
        np.testing.assert_allclose(reward_mjx, reward_cpu, atol=2e-3, err_msg=f"step {step}")
    assert set(info_mjx[0]["reward_terms"]) == set(cpu.reward_names)
    cpu.close()
    mjx.close()


def test_mjx_episodes_end_and_restart_inside_the_step():
    """Falls terminate, the time limit truncates, terminal observations and Monitor episode info come out."""
    env = zerith_gym.make_vec_env(
        2, seed=1, backend="mjx", scenario="nominal", command=COMMAND, episode_steps=12
    )
    env.reset()
    rng = np.random.default_rng(0)
    ended = []
    for t in range(24):
        obs, _, dones, infos = env.step(rng.uniform(-1, 1, (2, 12)))
        for i in np.flatnonzero(dones):
            info = infos[i]
            ended.append((t, info["TimeLimit.truncated"], info["episode"]["l"]))
            assert info["terminal_observation"]["policy"].shape == (46,)
            assert not np.array_equal(info["terminal_observation"]["policy"], obs["policy"][i])
            assert np.all(obs["policy"][i][7:10] == np.float32(COMMAND))  # a new episode's command
    assert ended, "no episode ended in 24 steps of 12-step episodes"
    assert all(length <= 12 for _, _, length in ended)
    assert any(truncated and length == 12 for _, truncated, length in ended)


def test_mjx_forces_act_on_the_bodies_of_the_current_target_only(nominal_pair):
    """The robust scenario's forces take turns between centroid, hands and feet on MJX as on the CPU (the
    shared env follows it by `set_scenario`, its compiled step unchanged)."""
    from zerith_gym.core.disturbances import FORCE_TARGET_NAMES
    from zerith_gym.core.scenarios import scaled_scenario

    env = nominal_pair[1]
    nominal = env.robots.scenario
    gentle = scaled_scenario(SCENARIOS["robust"], 0.2)
    env.robots.set_scenario(gentle)
    table = gentle.force.table(2000)
    model = env.robots.physics.model
    bodies = {name: [model.body(b).id for b in names] for name, names in robot.ZERITH1.force_bodies.items()}
    _restart(env)
    try:
        seen = _targets_pushed(env, table, bodies)
    finally:
        env.robots.set_scenario(nominal)
    assert seen == set(FORCE_TARGET_NAMES)


def _targets_pushed(env, table, bodies) -> set:
    """Step `env` with zero actions; check that each step's force acts on its target's bodies only, and
    return the targets that were pushed."""
    from zerith_gym.core.disturbances import FORCE_TARGET_NAMES

    seen = set()
    for _ in range(520):  # every target's phases come within 400 steps of any start phase
        task = env.robots.state.task
        step_count = np.asarray(task.step_count + task.force_offset)  # the table step about to be simulated
        _, _, dones, infos = env.step(np.zeros((env.num_envs, 12)))
        applied = np.asarray(env.robots.state.data.xfrc_applied)[:, :, :3]
        for i, info in enumerate(infos):
            if dones[i]:
                continue
            target = FORCE_TARGET_NAMES[table.target[step_count[i]]]
            for name, ids in bodies.items():
                expected = info["external_force"] if name == target else np.zeros(3)
                np.testing.assert_allclose(
                    applied[i, ids], np.broadcast_to(expected, (len(ids), 3)), atol=1e-5
                )
            if np.any(info["external_force"]):
                seen.add(target)
    return seen


def test_mjx_randomizes_like_the_cpu_backend():
    """Domain parameters, reset poses and commands of "train": same ranges and distributions (KS test)."""
    mjx = zerith_gym.make_vec_env(128, backend="mjx", scenario="train")
    cpu = zerith_gym.make_vec_env(256, seed=0, backend="cpu", workers=0, scenario="train")
    cpu.reset()
    samples_mjx = []
    for seed in range(4):
        mjx.seed(seed)
        mjx.reset()
        state = mjx.robots.state
        task = state.task
        samples_mjx.append(np.column_stack([task.domain_vector, task.command, state.data.qpos[:, 7:]]))
        # The model fields of each robot are those its domain parameters give.
        expected = domain_model_fields(
            mjx.robots.physics.nominal, DomainParams.from_vector(np.asarray(task.domain_vector, float))
        )
        for name, values in expected.items():
            np.testing.assert_allclose(np.asarray(state.fields[name]), values, rtol=1e-5, atol=1e-6)
    task = cpu.robots.task.state
    joints = np.array([d.qpos[7:] for d in cpu.robots.sim.datas])
    samples_cpu = np.column_stack([task.domain_vector, task.command, joints])
    samples_mjx = np.concatenate(samples_mjx)
    low, high = scenario_arrays(SCENARIOS["train"], None, 1000, HUMANOID_TASK)[1:3]
    domain = samples_mjx[:, :DOMAIN_VECTOR_SIZE]
    assert np.all(domain >= low - 1e-6) and np.all(domain <= high + 1e-6)
    varying = np.flatnonzero(samples_cpu.std(axis=0) > 0)
    p_values = [stats.ks_2samp(samples_cpu[:, k], samples_mjx[:, k]).pvalue for k in varying]
    assert min(p_values) > 1e-3 / len(varying), f"a distribution differs (p = {min(p_values):.2g})"
    cpu.close()


@pytest.fixture(scope="module")
def train_env():
    from stable_baselines3.common.vec_env import VecNormalize

    env = VecNormalize(zerith_gym.make_vec_env(8, seed=0, backend="mjx", scenario="train"), gamma=0.99)
    yield env
    env.close()


@pytest.mark.parametrize("algo", ["ppo", "huri"])
def test_sb3_ppo_and_huri_train_on_mjx_unchanged(train_env, algo, tmp_path):
    from stable_baselines3 import PPO

    from sb3_huri import HuRiPPO

    cls = PPO if algo == "ppo" else HuRiPPO
    policy = "MultiInputPolicy" if algo == "ppo" else "MlpPolicy"
    model = cls(policy, train_env, n_steps=16, batch_size=64, n_epochs=1, seed=0)
    model.learn(256)
    assert model.num_timesteps == 256
    assert len(model.ep_info_buffer) >= 0 and np.isfinite(model.logger.name_to_value["train/loss"])
    model.save(tmp_path / "model")
    loaded = cls.load(tmp_path / "model", env=train_env)
    obs = train_env.reset()
    np.testing.assert_array_equal(
        loaded.predict(obs, deterministic=True)[0], model.predict(obs, deterministic=True)[0]
    )


@pytest.mark.slow  # its own MJX compile; RL Zoo's env_kwargs path is the CPU's (tests/test_zoo.py)
def test_rl_zoo_trains_on_mjx_through_env_kwargs(tmp_path):
    command = [
        sys.executable, "-m", "rl_zoo3.train", "--algo", "huri", "--env", "Zerith1-v0",
        "-n", "128", "--seed", "0", "--eval-freq", "-1", "-f", str(tmp_path),
        "--env-kwargs", "backend:'mjx'", "solver_iterations:4", "ls_iterations:8",
        "--hyperparams", "n_envs:8", "n_steps:16", "batch_size:64", "n_epochs:1", "callback:None",
    ]  # fmt: skip
    result = subprocess.run(command, capture_output=True, text=True, timeout=600, env=os.environ.copy())
    assert result.returncode == 0, result.stderr[-3000:]
    run = tmp_path / "huri" / "Zerith1-v0_1"
    assert (run / "Zerith1-v0.zip").exists()
    assert "backend: mjx" in (run / "Zerith1-v0" / "args.yml").read_text()


def test_mjx_keeps_the_robots_contract(nominal_pair):
    from zerith_gym.core.contract import Robots

    env = nominal_pair[1]
    members = [name for name in vars(Robots) if not name.startswith("_")] + ["num_robots", "scenario"]
    assert all(hasattr(env.robots, name) for name in members)


def test_bad_backend_options_get_clear_errors():
    with pytest.raises(ValueError, match="unknown backend 'gpu'; valid backends: cpu, mjx"):
        zerith_gym.make_vec_env(2, backend="gpu")
    with pytest.raises(ValueError, match="options of the cpu backend"):
        zerith_gym.make_vec_env(2, backend="mjx", workers=1)
    with pytest.raises(ValueError, match="options of the mjx backend"):
        zerith_gym.make_vec_env(2, backend="cpu", solver_iterations=4)
    with pytest.raises(ValueError, match="solver iterations must be a positive integer"):
        zerith_gym.make_vec_env(2, backend="mjx", solver_iterations=0)


def test_mjx_robots_keep_their_starting_tiles():
    """A resumed terrain run asks for each robot's tile; MJX can only give the one it started on."""
    env = zerith_gym.make_vec_env(6, seed=0, backend="mjx", scenario="terrain")
    env.set_options({"tile": (9, 0)})
    with pytest.raises(ValueError, match=r"robot 0's is \(0, 0\), not \(9, 0\)"):
        env.reset()
    env.close()
