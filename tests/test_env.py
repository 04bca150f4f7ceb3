"""Zerith1-v0 API: registration, checkers, spaces, determinism, info, bad input, rendering."""

from __future__ import annotations

import gymnasium as gym
import mujoco
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env as gym_check_env
from stable_baselines3.common.env_checker import check_env as sb3_check_env

import zerith_gym
from zerith_gym import Zerith1Env
from zerith_gym.zerith1.observations import CRITIC_SIZE, POLICY_SIZE, critic_in_units
from zerith_gym.zerith1.rewards import REWARD_NAMES

STEP_INFO_KEYS = {"fall", "sim_unstable", "lin_vel_error", "ang_vel_error", "external_force", "command"}


def rollout(env: gym.Env, seed: int, steps: int, action_seed: int = 0) -> list:
    obs, _ = env.reset(seed=seed)
    actions = np.random.default_rng(action_seed).uniform(-1, 1, size=(steps, 12))
    trace = [obs]
    for action in actions:
        obs, reward, terminated, truncated, _ = env.step(action)
        trace.append((obs, reward))
        if terminated or truncated:
            trace.append(env.reset()[0])
    return trace


def flat(trace: list) -> np.ndarray:
    parts = []
    for item in trace:
        obs, reward = item if isinstance(item, tuple) else (item, 0.0)
        parts += [obs["policy"], obs["critic"], [reward]] if isinstance(obs, dict) else [obs, [reward]]
    return np.concatenate([np.asarray(p, dtype=np.float64).ravel() for p in parts])


def test_registered_ids_make_the_env():
    for env_id in ("Zerith1-v0", "zerith_gym:Zerith1-v0"):
        env = gym.make(env_id)
        assert isinstance(env.unwrapped, Zerith1Env)
        assert env.spec.max_episode_steps == 1000
        env.close()


@pytest.mark.parametrize("obs_mode", ["dict", "policy"])
def test_gymnasium_and_sb3_checkers_pass(obs_mode):
    env = Zerith1Env(scenario="train", obs_mode=obs_mode)
    gym_check_env(env, skip_render_check=True)  # includes reset determinism with seeds
    sb3_check_env(Zerith1Env(scenario="train", obs_mode=obs_mode), warn=True)


def test_observation_shapes_dtypes_and_action_space():
    env = Zerith1Env()
    obs, info = env.reset(seed=3)
    assert (
        env.action_space.shape == (12,)
        and env.action_space.low.min() == -1
        and env.action_space.high.max() == 1
    )
    assert obs["policy"].shape == (POLICY_SIZE,) == (46,) and obs["policy"].dtype == np.float32
    assert obs["critic"].shape == (CRITIC_SIZE,) and obs["critic"].dtype == np.float32
    assert env.observation_space.contains(obs)
    assert set(info) == {"command"}
    obs, reward, _, _, info = env.step(env.action_space.sample())
    assert env.observation_space.contains(obs)
    assert isinstance(reward, float) and np.isfinite(reward)
    assert set(info) >= STEP_INFO_KEYS
    flat_env = Zerith1Env(obs_mode="policy")
    flat_obs, _ = flat_env.reset(seed=3)
    assert flat_obs.shape == (46,) and flat_env.observation_space.contains(flat_obs)


def test_same_seed_same_trajectory_and_different_seed_differs():
    a = flat(rollout(Zerith1Env(), seed=7, steps=120))
    b = flat(rollout(Zerith1Env(), seed=7, steps=120))
    c = flat(rollout(Zerith1Env(), seed=8, steps=120))
    np.testing.assert_array_equal(a, b)
    assert a.shape != c.shape or not np.array_equal(a, c)


def test_actions_outside_the_box_are_clipped():
    clipped = Zerith1Env(scenario="nominal")
    raw = Zerith1Env(scenario="nominal")
    clipped.reset(seed=1)
    raw.reset(seed=1)
    action = np.linspace(-3.0, 3.0, 12)
    for _ in range(5):
        obs_c, *_ = clipped.step(np.clip(action, -1, 1))
        obs_r, *_ = raw.step(action)
    np.testing.assert_array_equal(obs_c["critic"], obs_r["critic"])
    np.testing.assert_allclose(obs_r["policy"][34:46], np.clip(action, -1, 1), atol=1e-6)


def test_fixed_command_and_reset_option():
    env = Zerith1Env(scenario="nominal", command=(0.5, 0.0, 0.1))
    obs, info = env.reset(seed=0)
    np.testing.assert_allclose(info["command"], (0.5, 0.0, 0.1))
    np.testing.assert_allclose(obs["policy"][7:10], (0.5, 0.0, 0.1), atol=1e-7)
    _, info = env.reset(seed=0, options={"command": (0.2, 0.1, 0.0)})
    np.testing.assert_allclose(info["command"], (0.2, 0.1, 0.0))
    test_env = Zerith1Env(scenario="continuous-hands")
    _, info = test_env.reset(seed=0)
    np.testing.assert_allclose(info["command"], (1.0, 0.0, 0.0))


def test_commands_are_resampled_within_the_training_ranges():
    env = Zerith1Env(scenario="nominal")
    commands = set()
    for seed in range(4):
        _, info = env.reset(seed=seed)
        commands.add(tuple(info["command"]))
        for _ in range(251):  # commands are redrawn every 5 s
            _, _, terminated, truncated, info = env.step(np.zeros(12))
            assert not (terminated or truncated)
        commands.add(tuple(info["command"]))
    values = np.array(sorted(commands))
    assert len(values) == 8
    assert (values[:, 0] >= 0).all() and (values[:, 0] <= 0.7).all()
    assert (np.abs(values[:, 1]) <= 0.3).all() and (np.abs(values[:, 2]) <= 0.5).all()


def test_truncation_at_20_seconds_with_episode_term_sums():
    env = Zerith1Env(scenario="nominal", command=(0.0, 0.0, 0.0))
    env.reset(seed=0)
    total = 0.0
    for step in range(1, 1001):
        _, reward, terminated, truncated, info = env.step(np.zeros(12))
        total += reward
        assert not terminated, f"fell at step {step}"
        assert list(info["reward_terms"]) == list(REWARD_NAMES)
        assert sum(info["reward_terms"].values()) == pytest.approx(reward, rel=1e-12, abs=1e-12)
        if truncated:
            break
    assert step == 1000 and truncated and not info["fall"]
    assert set(info["episode_terms"]) == set(REWARD_NAMES)
    assert sum(info["episode_terms"].values()) == pytest.approx(total, rel=1e-9, abs=1e-9)
    with pytest.raises(RuntimeError):
        env.step(np.zeros(12))


def test_reward_weights_override():
    base = Zerith1Env(scenario="nominal")
    zero = Zerith1Env(scenario="nominal", reward_weights=dict.fromkeys(REWARD_NAMES, 0.0))
    alive = Zerith1Env(scenario="nominal", reward_weights={**dict.fromkeys(REWARD_NAMES, 0.0), "alive": 2.0})
    for env in (base, zero, alive):
        env.reset(seed=0)
    action = np.full(12, 0.1)
    assert zero.step(action)[1] == 0.0
    assert alive.step(action)[1] == pytest.approx(2.0 * 0.02)
    assert base.step(action)[1] != 0.0


def test_joint_acceleration_penalty_uses_consecutive_joint_velocities():
    weights = {**dict.fromkeys(REWARD_NAMES, 0.0), "joint_accelerations": 1.0}
    env = Zerith1Env(scenario="nominal", reward_weights=weights)
    obs, _ = env.reset(seed=0)
    joint_velocity = slice(22, 34)  # noiseless joint velocities in the critic observation
    actions = np.random.default_rng(0).uniform(-1, 1, size=(5, 12))
    for action in actions:
        previous = critic_in_units(obs["critic"].astype(np.float64))[joint_velocity]
        obs, reward, *_ = env.step(action)
        acceleration = (critic_in_units(obs["critic"].astype(np.float64))[joint_velocity] - previous) / 0.02
        assert reward == pytest.approx(0.02 * np.sum(acceleration**2), rel=1e-3)
        assert reward > 0.0


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"scenario": "moon"}, "valid scenarios: train, nominal"),
        ({"obs_mode": "image"}, "valid values: dict, policy"),
        ({"render_mode": "ascii"}, "valid values: None, human, rgb_array"),
        ({"reward_weights": {"speed": 1.0}}, "valid terms: alive"),
        ({"reward_weights": {"alive": float("nan")}}, "must be finite"),
        ({"command": (1.0, 0.0)}, "command must be three finite numbers"),
    ],
)
def test_bad_constructor_arguments_raise(kwargs, match):
    with pytest.raises(ValueError, match=match):
        Zerith1Env(**kwargs)
    with pytest.raises(ValueError, match=match):
        gym.make("Zerith1-v0", **kwargs)


def test_bad_actions_and_options_raise():
    env = Zerith1Env()
    with pytest.raises(RuntimeError, match="before reset"):
        env.step(np.zeros(12))
    with pytest.raises(ValueError, match="valid options: command, tile"):
        env.reset(seed=0, options={"speed": 1})
    env.reset(seed=0)
    for bad in (np.full(12, np.nan), np.r_[np.zeros(11), np.inf]):
        with pytest.raises(ValueError, match="NaN or infinite"):
            env.step(bad)
    with pytest.raises(ValueError, match=r"shape \(12,\)"):
        env.step(np.zeros(10))


def test_forced_instability_ends_the_episode_with_finite_outputs():
    env = Zerith1Env(scenario="nominal")
    obs, _ = env.reset(seed=0)
    env.step(np.zeros(12))
    env.data.qvel[:] = 1e12  # beyond MuJoCo's bound: it warns and resets the state
    obs, reward, terminated, truncated, info = env.step(np.zeros(12))
    assert info["sim_unstable"] and truncated and not terminated and not info["fall"]
    assert reward == 0.0
    assert np.isfinite(obs["policy"]).all() and np.isfinite(obs["critic"]).all()
    assert all(np.isfinite(v) for v in info["episode_terms"].values())
    obs, _ = env.reset()
    assert np.isfinite(obs["critic"]).all()
    _, _, _, _, info = env.step(np.zeros(12))
    assert not info["sim_unstable"]


def test_package_exports():
    assert set(zerith_gym.SCENARIOS) == {
        "train", "nominal", "continuous-centroid", "continuous-hands", "continuous-feet", "sudden-centroid",
        "sudden-hands", "sudden-feet", "load", "friction", "load-friction", "uneven", "side-impact", "robust",
        "terrain", "multi-terrain", "platform-0.40", "platform-0.45", "quadruped-train", "quadruped-rough",
    }  # fmt: skip
    assert tuple(zerith_gym.DEFAULT_REWARD_WEIGHTS) == zerith_gym.REWARD_NAMES


def test_rgb_array_rendering_follows_the_robot():
    try:
        env = Zerith1Env(scenario="nominal", render_mode="rgb_array", width=160, height=120)
        env.reset(seed=0)
        first = env.render()
    except Exception as error:  # no usable OpenGL (EGL) on this machine
        pytest.skip(f"rendering unavailable: {error}")
    assert first.shape == (120, 160, 3) and first.dtype == np.uint8
    assert first.std() > 5.0  # not a blank frame
    for _ in range(10):
        env.step(np.zeros(12))
    assert env.render().shape == (120, 160, 3)

    # Move the robot 5.6 m away: a camera that follows it still sees it (the white robot's pixels; the
    # white horizon line, also counted, is about half of them and stays in any camera's view).
    def white_pixels(frame: np.ndarray) -> int:
        return int((frame.min(axis=2) > 170).sum())

    before = white_pixels(env.render())
    model, data = env.robots.sim.models[0], env.robots.sim.datas[0]
    data.qpos[:2] += 4.0
    mujoco.mj_forward(model, data)
    assert white_pixels(env.render()) > 0.9 * before
    env.close()
