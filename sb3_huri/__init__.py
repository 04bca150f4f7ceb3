"""HuRi: adaptive risk-aware distributional PPO for Stable-Baselines3."""

from sb3_huri.huri import VARIANTS, HuRiPolicy, HuRiPPO, RiskAssessment
from sb3_huri.version import __version__

__all__ = ["VARIANTS", "HuRiPPO", "HuRiPolicy", "RiskAssessment", "__version__"]
