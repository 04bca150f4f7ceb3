"""Environment classes."""

from zerith_gym.envs.zerith1 import Zerith1Env

__all__ = ["Zerith1Env"]
