"""zerith_gym: the Zerith1-v0 humanoid locomotion environment (MuJoCo, Gymnasium).

Importing the package registers `Zerith1-v0` and `Go2Like-v0` (a Go2-like quadruped on legged_gym's task):

    import gymnasium as gym
    import zerith_gym  # noqa: F401

    env = gym.make("Zerith1-v0", scenario="nominal", obs_mode="policy")

`zerith_gym.make_vec_env(n, seed=...)` gives n robots as a Stable-Baselines3 VecEnv (`ZerithVecEnv`);
it is imported on first use, so importing the package does not import torch. `backend="mjx"` simulates
them with MuJoCo MJX on JAX's default device (`zerith_gym.mjx`, the optional `mjx` extra).

Inside: `core/` is the step every robot shares, and imports no robot; `zerith1/` and `go2like/` are the
robots, each with its constants, MJCF, task and env class; `robots.py` names them for the `robot` option
(`options.py`); `terrain/` is the ground; `cpu/` and `mjx/` simulate batches of robots; `sb3/` is the
Stable-Baselines3 vec env and callbacks.
"""

from typing import Any

import gymnasium as gym
from gymnasium.envs.registration import register

from zerith_gym.core.scenarios import SCENARIOS
from zerith_gym.core.task import EPISODE_STEPS
from zerith_gym.zerith1.env import Zerith1Env
from zerith_gym.zerith1.rewards import DEFAULT_REWARD_WEIGHTS, REWARD_NAMES

__all__ = [
    "DEFAULT_REWARD_WEIGHTS",
    "GO2LIKE_ID",
    "REWARD_NAMES",
    "SCENARIOS",
    "ZERITH1_ID",
    "Zerith1Env",
    "ZerithVecEnv",
    "make_vec_env",
    "robot_of",
]

ZERITH1_ID = "Zerith1-v0"
GO2LIKE_ID = "Go2Like-v0"
ZERITH1_ENTRY_POINT = "zerith_gym.zerith1.env:Zerith1Env"
GO2LIKE_ENTRY_POINT = "zerith_gym.go2like.env:Go2LikeEnv"
ROBOT_ENTRY_POINTS = {ZERITH1_ENTRY_POINT: "zerith1", GO2LIKE_ENTRY_POINT: "go2like"}
"""The entry points of the envs `make_vec_env` batches, and the robot (its `robot` option) of each."""

register(id=ZERITH1_ID, entry_point=ZERITH1_ENTRY_POINT, max_episode_steps=EPISODE_STEPS)
register(id=GO2LIKE_ID, entry_point=GO2LIKE_ENTRY_POINT, max_episode_steps=EPISODE_STEPS)


def robot_of(env_id: str) -> str:
    """The robot (`make_vec_env`'s `robot` option) of a registered Zerith env id, also one registered under
    another id with a Zerith entry point; ValueError for an env id that is not one."""
    entry_point = gym.spec(env_id).entry_point
    if entry_point not in ROBOT_ENTRY_POINTS:
        raise ValueError(f"{env_id} is not a Zerith env ({ZERITH1_ID}, {GO2LIKE_ID})")
    return ROBOT_ENTRY_POINTS[entry_point]


def __getattr__(name: str) -> Any:
    if name in ("ZerithVecEnv", "make_vec_env"):
        from zerith_gym.sb3 import vec_env

        return getattr(vec_env, name)
    raise AttributeError(f"module 'zerith_gym' has no attribute {name!r}")
