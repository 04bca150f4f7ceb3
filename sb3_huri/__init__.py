"""HuRi: adaptive risk-aware distributional PPO for Stable-Baselines3."""

from sb3_huri.version import __version__

__all__ = ["__version__"]
