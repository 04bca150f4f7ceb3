"""The paper's methods as presets of HuRiPPO: each one is ``HuRiPPO(..., variant=name)``.

A preset and HuRiPPO's risk arguments together make its ``RiskModel`` (``sb3_huri.huri.risk``), where they
are resolved and checked.
"""

from dataclasses import dataclass


@dataclass(frozen=True)
class RiskPreset:
    """How a method turns the critic's return distribution into the value PPO's advantages use.

    :param distributional: quantile critic (energy-distance and expectation losses, SR(lambda) targets);
        ``False`` is PPO's scalar critic (MSE on TD(lambda) returns)
    :param distortion: ``"wang"`` or ``"cvar"`` (unused without a distributional critic)
    :param use_iqr: risk parameter from the IQR band of the predicted atoms (else the fixed one)
    :param use_rnd: add ``tanh(RND error)`` of the critic state to the risk parameter
    """

    distributional: bool
    distortion: str = "wang"
    use_iqr: bool = False
    use_rnd: bool = False


VARIANTS: dict[str, RiskPreset] = {
    # PPO: scalar critic, MSE value loss, GAE on the value; same asymmetric networks.
    "baseline": RiskPreset(distributional=False),
    # Quantile critic, CVaR distortion at the fixed level alpha = cvar_alpha (0.5).
    "cvar0.5": RiskPreset(distributional=True, distortion="cvar"),
    # Wang distortion with beta = beta_IQR only (paper: HuRi w/o RND).
    "huri-no-rnd": RiskPreset(distributional=True, distortion="wang", use_iqr=True),
    # Wang distortion with beta = wang_beta (0) + tanh(RND error) (paper A.5: HuRi w/o IQR).
    "huri-no-iqr": RiskPreset(distributional=True, distortion="wang", use_rnd=True),
    # The full method: beta = beta_IQR + tanh(RND error), Wang distortion.
    "huri": RiskPreset(distributional=True, distortion="wang", use_iqr=True, use_rnd=True),
    # Paper A.8: CVaR with alpha = alpha_IQR (1, or 0.5 above t_max) + tanh(RND error), clipped to 1.
    "huri-cvar": RiskPreset(distributional=True, distortion="cvar", use_iqr=True, use_rnd=True),
}

# Risk parameter below / within / above the IQR thresholds, per distortion (paper Algorithm 1 and A.8).
DEFAULT_IQR_RISK_LEVELS: dict[str, tuple[float, float, float]] = {
    "wang": (-1.0, 0.0, 1.0),
    "cvar": (1.0, 1.0, 0.5),
}
