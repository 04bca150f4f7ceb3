"""zerith_gym: the Zerith1-v0 humanoid locomotion environment (MuJoCo, Gymnasium).

Importing the package registers `Zerith1-v0` and `Go2Like-v0` (a Go2-like quadruped on legged_gym's task):

    import gymnasium as gym
    import zerith_gym  # noqa: F401

    env = gym.make("Zerith1-v0", scenario="nominal", obs_mode="policy")

`zerith_gym.make_vec_env(n, seed=...)` gives n robots as a Stable-Baselines3 VecEnv (`ZerithVecEnv`);
it is imported on first use, so importing the package does not import torch. `backend="mjx"` simulates
them with MuJoCo MJX on JAX's default device (`zerith_gym.mjx`, the optional `mjx` extra).
"""

from typing import Any

from gymnasium.envs.registration import register

from zerith_gym.envs.zerith1 import Zerith1Env
from zerith_gym.rewards import DEFAULT_REWARD_WEIGHTS, REWARD_NAMES
from zerith_gym.scenarios import SCENARIOS
from zerith_gym.task import EPISODE_STEPS

__all__ = [
    "DEFAULT_REWARD_WEIGHTS",
    "REWARD_NAMES",
    "SCENARIOS",
    "Zerith1Env",
    "ZerithVecEnv",
    "make_vec_env",
]

register(
    id="Zerith1-v0",
    entry_point="zerith_gym.envs.zerith1:Zerith1Env",
    max_episode_steps=EPISODE_STEPS,
)
register(
    id="Go2Like-v0",
    entry_point="zerith_gym.envs.go2like:Go2LikeEnv",
    max_episode_steps=EPISODE_STEPS,
)


def __getattr__(name: str) -> Any:
    if name in ("ZerithVecEnv", "make_vec_env"):
        from zerith_gym.sb3 import vec_env

        return getattr(vec_env, name)
    raise AttributeError(f"module 'zerith_gym' has no attribute {name!r}")
