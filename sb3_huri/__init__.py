"""HuRi: adaptive risk-aware distributional PPO for Stable-Baselines3."""

from sb3_huri.huri import METHODS, HuRiPolicy, HuRiPPO, RiskAssessment, UnnormalizedRewardWarning
from sb3_huri.version import __version__

__all__ = ["METHODS", "HuRiPPO", "HuRiPolicy", "RiskAssessment", "UnnormalizedRewardWarning", "__version__"]
