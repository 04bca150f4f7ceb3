"""HuRiPPO: adaptive risk-aware distributional PPO."""

from sb3_huri.huri.huri import HuRiPPO
from sb3_huri.huri.hyperparameters import UnnormalizedRewardWarning
from sb3_huri.huri.methods import DEFAULT_METHOD, METHODS, RiskPreset, method_of_saved
from sb3_huri.huri.policies import HuRiPolicy, MlpPolicy, MultiInputPolicy
from sb3_huri.huri.risk import RiskAssessment, RiskModel

__all__ = [
    "DEFAULT_METHOD",
    "METHODS",
    "HuRiPPO",
    "HuRiPolicy",
    "MlpPolicy",
    "MultiInputPolicy",
    "RiskAssessment",
    "RiskModel",
    "RiskPreset",
    "UnnormalizedRewardWarning",
    "method_of_saved",
]
