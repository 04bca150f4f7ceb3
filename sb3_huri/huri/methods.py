"""The paper's methods as presets of HuRiPPO: each one is ``HuRiPPO(..., method=name)``.

A method's name is the same everywhere: HuRiPPO's ``method``, the RL Zoo algorithm (``--algo``), the
experiment grid and the run folders (``runs/<method>/``, ``trained_agents/<method>/``). A preset and
HuRiPPO's risk arguments together make its ``RiskModel`` (``sb3_huri.huri.risk``), where they are resolved
and checked.
"""

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any


@dataclass(frozen=True)
class RiskPreset:
    """How a method turns the critic's return distribution into the value PPO's advantages use.

    :param distributional: quantile critic (energy-distance and expectation losses, SR(lambda) targets);
        ``False`` is PPO's scalar critic (MSE on TD(lambda) returns)
    :param distortion: ``"wang"`` or ``"cvar"`` (unused without a distributional critic)
    :param use_iqr: risk parameter from the IQR band of the predicted atoms (else the fixed one)
    :param use_rnd: add ``tanh(RND error)`` of the critic state to the risk parameter
    :param iqr_band: how the IQR band's thresholds are read (``sb3_huri.huri.risk.RiskModel``):
        ``"absolute"``, in units of the normalized return (the paper's ``[0.3, 0.7]`` as printed), or
        ``"percentile"``, percentiles of the critic's own IQR over recent rollouts (scale-free)
    :param td_level: at which risk level a TD error of the advantages values its two states
        (``sb3_huri.common.risk_gae``): ``"state"``, each at its own (every method), or ``"step"``, both at
        the level of the state the step starts from (``HuRiPPO(td_level="step")``; docs/huri.md, "Each
        step at its own level": it did not learn Pendulum)
    """

    distributional: bool
    distortion: str = "wang"
    use_iqr: bool = False
    use_rnd: bool = False
    iqr_band: str = "absolute"
    td_level: str = "state"


METHODS: dict[str, RiskPreset] = {
    # PPO: scalar critic, MSE value loss, GAE on the value; same asymmetric networks.
    "huri-baseline": RiskPreset(distributional=False),
    # The quantile critic of every HuRi method (energy distance, SR(lambda) targets) with a risk-neutral
    # value: beta fixed at wang_beta (0), no IQR band, no RND. At beta = 0 the weights are uniform, V_beta is
    # the atom mean and eq. 5's distorted expectation loss is identically zero (DPPO with a neutral measure).
    "huri-neutral": RiskPreset(distributional=True, distortion="wang"),
    # Quantile critic, CVaR distortion at the fixed level alpha = cvar_alpha (0.5).
    "huri-cvar0.5": RiskPreset(distributional=True, distortion="cvar"),
    # Wang distortion with beta = beta_IQR only (paper: HuRi w/o RND).
    "huri-no-rnd": RiskPreset(distributional=True, distortion="wang", use_iqr=True),
    # Wang distortion with beta = wang_beta (0) + tanh(RND error) (paper A.5: HuRi w/o IQR).
    "huri-no-iqr": RiskPreset(distributional=True, distortion="wang", use_rnd=True),
    # The full method: beta = beta_IQR + tanh(RND error), Wang distortion.
    "huri": RiskPreset(distributional=True, distortion="wang", use_iqr=True, use_rnd=True),
    # HuRi with a scale-free band: a state is averse when its critic's IQR is above the 70th percentile of the
    # IQRs of recent rollouts, seeking below the 30th (docs/huri.md, "Our reading").
    "huri-percentile": RiskPreset(
        distributional=True, distortion="wang", use_iqr=True, use_rnd=True, iqr_band="percentile"
    ),
    # Paper A.8: CVaR with alpha = alpha_IQR (1, or 0.5 above t_max) + tanh(RND error), clipped to 1.
    "huri-cvar": RiskPreset(distributional=True, distortion="cvar", use_iqr=True, use_rnd=True),
}

DEFAULT_METHOD = "huri"
"""``HuRiPPO``'s method when none is named: HuRi with the IQR band as the paper prints it, in units of the
normalized return. ``huri-percentile``, whose risk levels adapt per state whatever the reward's scale, was the
default until its first measured pair: it survived less than both PPO and ``huri`` on the same robots
(docs/huri.md, "Measured: the percentile band")."""

EARLIER_NAMES: dict[str, str] = {"baseline": "huri-baseline", "cvar0.5": "huri-cvar0.5"}
"""The methods whose name differs in models saved before HuRiPPO's ``variant`` became ``method``: earlier
name -> method (the others kept theirs)."""


def method_of_saved(attributes: Mapping[str, Any]) -> str | None:
    """The method of a saved model, from its attributes (a loaded model's ``__dict__``, or the data of its
    zip): its ``method``, or for a model saved before ``variant`` became ``method`` its ``variant`` under
    today's name (``baseline`` -> ``huri-baseline``, ``cvar0.5`` -> ``huri-cvar0.5``, the others unchanged).
    None for a model with neither (one of SB3's own PPO)."""
    if "variant" in attributes:
        return EARLIER_NAMES.get(attributes["variant"], attributes["variant"])
    return attributes.get("method")


# Risk parameter below / within / above the IQR thresholds, per distortion (paper Algorithm 1 and A.8).
DEFAULT_IQR_RISK_LEVELS: dict[str, tuple[float, float, float]] = {
    "wang": (-1.0, 0.0, 1.0),
    "cvar": (1.0, 1.0, 0.5),
}
