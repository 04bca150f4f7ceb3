"""Helpers shared by the tests: a Pendulum with an asymmetric observation, a logger writer that keeps every
value, an exact comparison of state dicts, a tiny version of the robust recipe's preset, and a program that
holds a run folder."""

from pathlib import Path

import gymnasium as gym
import numpy as np
import torch as th
from gymnasium import spaces
from stable_baselines3.common.env_util import make_vec_env
from stable_baselines3.common.logger import KVWriter

ROOT = Path(__file__).resolve().parent.parent

HOLD_RUN = "import sys\nfrom sb3_huri.runner.lock import hold_run\nwith hold_run(sys.argv[1]):\n"
HOLD_RUN += "    print('held', flush=True)\n    sys.stdin.read()\n"
"""A program that holds the run folder it is given (``sb3_huri.runner.lock``) until its input ends."""

SMALL = dict(n_steps=32, n_minibatches=4, n_epochs=2, policy_kwargs=dict(net_arch=[32, 32]))


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


def tiny_robust_preset(folder: Path, n_timesteps: int = 384, name: str = "tiny.yml") -> Path:
    """`hyperparams/huri_robust.yml` shrunk to seconds of training (4 robots, 16 steps each per rollout, one
    epoch, a 16-unit network), with a curriculum that may rise a stage per rollout, held back only by falls;
    written to `folder/name` as an RL Zoo hyperparameter file."""
    import yaml

    presets = yaml.safe_load((ROOT / "hyperparams" / "huri_robust.yml").read_text())
    preset = presets["Zerith1-v0"]
    preset.update(n_envs=4, n_steps=16, n_epochs=1, policy_kwargs="dict(net_arch=[16], log_std_init=-2.0)")
    preset["n_timesteps"] = n_timesteps
    preset["callback"][1]["zerith_gym.sb3.callbacks.RandomizationCurriculum"] = dict(
        steps=64, stages=4, max_fall_rate=1.0, gate_episodes=1
    )
    path = folder / name
    path.write_text(yaml.safe_dump({"Zerith1-v0": preset}))
    return path


def gae(rewards, values, starts, last_values, last_dones, gamma, lam) -> np.ndarray:
    """Generalized advantage estimation, step by step: `rewards`, `values` and `starts` of shape ``(steps,
    envs)``, the values after the last step and whether each env's last step ended an episode."""
    advantages = np.zeros_like(rewards)
    running = np.zeros(rewards.shape[1])
    for t in reversed(range(len(rewards))):
        if t == len(rewards) - 1:
            following, alive = last_values, 1.0 - last_dones
        else:
            following, alive = values[t + 1], 1.0 - starts[t + 1]
        delta = rewards[t] + gamma * following * alive - values[t]
        running = delta + gamma * lam * alive * running
        advantages[t] = running
    return advantages
