"""Building blocks of the HuRi algorithm: risk distortions, distributional losses and targets, RND."""

from sb3_huri.common.distortion import DISTORTIONS, cvar_weights, distortion_weights, wang_weights
from sb3_huri.common.energy import energy_distance
from sb3_huri.common.expectation import EXPECTATION_LOSSES, expectation_loss
from sb3_huri.common.quantiles import interpolated_quantile, interquartile_range, iqr_risk_level
from sb3_huri.common.rnd import RandomNetworkDistillation, RNDTrainingCallback
from sb3_huri.common.sr_lambda import sr_lambda_targets

__all__ = [
    "DISTORTIONS",
    "EXPECTATION_LOSSES",
    "RNDTrainingCallback",
    "RandomNetworkDistillation",
    "cvar_weights",
    "distortion_weights",
    "energy_distance",
    "expectation_loss",
    "interpolated_quantile",
    "interquartile_range",
    "iqr_risk_level",
    "sr_lambda_targets",
    "wang_weights",
]
