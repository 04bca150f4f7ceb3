"""Helpers shared by the HuRiPPO tests: a Pendulum with an asymmetric observation, a logger writer that
keeps every value, and an exact comparison of state dicts."""

import gymnasium as gym
import numpy as np
import torch as th
from gymnasium import spaces
from stable_baselines3.common.env_util import make_vec_env
from stable_baselines3.common.logger import KVWriter

SMALL = dict(n_steps=32, n_epochs=2, policy_kwargs=dict(net_arch=[32, 32]))


class PendulumWithCritic(gym.ObservationWrapper):
    """Pendulum with an asymmetric observation: the usual vector for the actor, the state for the critic."""

    def __init__(self, env: gym.Env):
        super().__init__(env)
        self.observation_space = spaces.Dict(
            {
                "policy": env.observation_space,
                "critic": spaces.Box(-np.inf, np.inf, (2,), np.float32),
            }
        )

    def observation(self, observation: np.ndarray) -> dict[str, np.ndarray]:
        return {"policy": observation, "critic": np.asarray(self.unwrapped.state, dtype=np.float32)}


def dict_env(n_envs: int = 2, seed: int = 0, max_episode_steps: int = 200):
    return make_vec_env(
        "Pendulum-v1",
        n_envs=n_envs,
        seed=seed,
        env_kwargs=dict(max_episode_steps=max_episode_steps),
        wrapper_class=PendulumWithCritic,
    )


class KeyRecorder(KVWriter):
    """Keeps every logged key/value."""

    def __init__(self):
        self.records: dict[str, list] = {}

    def write(self, key_values, key_excluded, step=0):
        for key, value in key_values.items():
            self.records.setdefault(key, []).append(value)


def state_dicts_equal(first: dict, second: dict) -> None:
    assert first.keys() == second.keys()
    for key in first:
        if isinstance(first[key], dict):
            state_dicts_equal(first[key], second[key])
        elif isinstance(first[key], th.Tensor):
            th.testing.assert_close(first[key], second[key], rtol=0, atol=0, msg=key)
        else:
            assert first[key] == second[key], key
