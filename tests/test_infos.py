"""The lazily built per-robot infos of a ZerithVecEnv step (zerith_gym.core.infos)."""

from __future__ import annotations

import numpy as np
import pytest
from stable_baselines3.common.vec_env import VecNormalize

import zerith_gym
from zerith_gym.core.infos import RobotInfo, StepInfos
from zerith_gym.zerith1.rewards import REWARD_NAMES


@pytest.fixture(scope="module")
def stepped():
    env = zerith_gym.make_vec_env(4, seed=0, scenario="train", workers=0, episode_steps=3)
    env.reset()
    results = [env.step(np.random.default_rng(k).uniform(-1, 1, (4, 12))) for k in range(3)]
    yield env, results
    env.close()


def test_each_info_reads_its_robot_from_the_step_arrays(stepped):
    _, results = stepped
    _, reward, _, infos = results[0]
    assert isinstance(infos, StepInfos) and all(isinstance(info, RobotInfo) for info in infos)
    out = infos.step.out
    for i, info in enumerate(infos):
        assert info["fall"] is bool(out.fall[i]) and info["lin_vel_error"] == float(out.lin_vel_error[i])
        np.testing.assert_array_equal(info["external_force"], infos.step.force[i])
        assert sum(info["reward_terms"].values()) == pytest.approx(float(reward[i]), abs=1e-5)
        assert info["TimeLimit.truncated"] is False and info.get("episode") is None
        assert set(info) == {
            "fall", "sim_unstable", "lin_vel_error", "ang_vel_error", "external_force", "command",
            "reward_terms", "terrain_level", "TimeLimit.truncated",
        }  # fmt: skip
        assert len(dict(info)) == len(info) == 9 and info["terrain_level"] == 0  # a plane: one level
        copied = info.copy()
        assert type(copied) is dict and copied.keys() == dict(info).keys()


def test_episode_ends_write_their_keys_and_keep_them(stepped):
    _, results = stepped
    _, _, dones, infos = results[2]  # every robot reaches the 3-step limit
    assert dones.all()
    for info in infos:
        assert info["TimeLimit.truncated"] is True and info["episode"]["l"] == 3
        assert set(info["episode_terms"]) == set(REWARD_NAMES)
        assert info["terminal_observation"]["policy"].shape == (46,)
        assert {"episode", "episode_terms", "terminal_observation"} <= set(info) and len(info) == 12
    info = infos[0]
    info["mine"] = 1
    assert infos[0]["mine"] == 1
    del info["mine"]
    assert "mine" not in info
    with pytest.raises(KeyError, match="computed from the step"):
        del info["fall"]
    with pytest.raises(KeyError):
        info["missing"]


def test_vecnormalize_normalizes_terminal_observations_in_place_and_keeps_the_arrays():
    env = VecNormalize(zerith_gym.make_vec_env(2, seed=0, workers=0, episode_steps=2), norm_reward=False)
    env.reset()
    for _ in range(2):
        _, _, dones, infos = env.step(np.zeros((2, 12)))
    assert dones.all() and isinstance(infos, StepInfos) and infos.step.out.terminated.shape == (2,)
    terminal = infos[0]["terminal_observation"]["policy"]
    out = infos.step.out
    expected = env.normalize_obs({"policy": out.policy_obs[:1], "critic": out.critic_obs[:1]})["policy"][0]
    np.testing.assert_allclose(terminal, expected, atol=1e-5)
    env.close()
