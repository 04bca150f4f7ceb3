"""HuRiPPO: adaptive risk-aware distributional PPO."""

from sb3_huri.huri.huri import HuRiPPO, UnnormalizedRewardWarning
from sb3_huri.huri.policies import HuRiPolicy, MlpPolicy, MultiInputPolicy
from sb3_huri.huri.risk import RiskAssessment, RiskModel
from sb3_huri.huri.variants import VARIANTS, RiskPreset

__all__ = [
    "VARIANTS",
    "HuRiPPO",
    "HuRiPolicy",
    "MlpPolicy",
    "MultiInputPolicy",
    "RiskAssessment",
    "RiskModel",
    "RiskPreset",
    "UnnormalizedRewardWarning",
]
