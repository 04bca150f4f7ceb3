"""HuRiPPO's risk model: how the critic's return distribution becomes the value PPO's advantages use.

One frozen :class:`RiskModel` holds every setting of it (scalar or quantile critic, distortion, whether the
IQR band and/or RND novelty set the risk level, the fixed parameters, the IQR band) and is the one place
they are checked. It computes each state's risk level, the distortion weights and the distorted value,
and names the rollout statistics the algorithm logs.

The risk level is Wang's ``beta`` for the Wang distortion and CVaR's ``alpha`` for CVaR; the code and the
logs call it ``risk`` wherever both are meant.
"""

import math
from collections.abc import Callable
from dataclasses import asdict, dataclass, fields, replace
from typing import Any, NamedTuple

import numpy as np
import torch as th

from sb3_huri.common.distortion import DISTORTIONS, distortion_weights
from sb3_huri.common.quantiles import interquartile_range, iqr_risk_level, sorted_atoms
from sb3_huri.common.risk_gae import TD_LEVELS
from sb3_huri.huri.methods import DEFAULT_IQR_RISK_LEVELS, METHODS

IQR_BANDS = ("absolute", "percentile")
"""Readings of the IQR band's thresholds: in units of the normalized return, or percentiles of the IQR."""

DEFAULT_N_QUANTILES = 64
"""Critic atoms ``N`` when neither the argument nor ``policy_kwargs`` gives them (paper Table 3)."""

WANG_LOG_KEYS = {
    "rollout/risk_mean": "rollout/beta_mean",
    "rollout/risk_iqr_mean": "rollout/beta_iqr_mean",
    "rollout/risk_rnd_mean": "rollout/beta_rnd_mean",
    "rollout/iqr_above_share": "rollout/beta_iqr_averse",
    "rollout/iqr_within_share": "rollout/beta_iqr_neutral",
    "rollout/iqr_below_share": "rollout/beta_iqr_seeking",
}
"""Logged keys -> the names they also have with the Wang distortion, where the risk level is ``beta`` (the
names of earlier logs, kept so that their curves go on)."""


class RiskAssessment(NamedTuple):
    """The critic's view of observations (numpy): one row per observation for a batch, unbatched for one."""

    atoms: np.ndarray
    """Predicted return atoms, sorted, shape ``(batch, n_quantiles)`` (one observation: ``(N,)``)."""
    value: np.ndarray
    """Distorted value ``V_beta``, the value the advantages use."""
    risk: np.ndarray
    """Risk level: Wang's ``beta`` (> 0 risk-averse) or CVaR's ``alpha``."""
    iqr: np.ndarray
    """Interquartile range of the atoms."""
    rnd_error: np.ndarray
    """RND novelty of the critic input (zero without RND); ``beta_RND = tanh(rnd_error)``."""
    risk_iqr: np.ndarray
    """The IQR band's part of the risk level (the fixed level without ``use_iqr``)."""
    risk_rnd: np.ndarray
    """The RND part of the risk level, ``tanh(rnd_error)`` (zero without RND)."""


class RiskReading(NamedTuple):
    """Everything :meth:`RiskModel.assess` computes for a batch of states, one row per state (torch tensors,
    or their numpy copies)."""

    atoms: Any
    """Sorted atoms ``(B, N)``."""
    value: Any
    """Distorted value ``V_beta``."""
    risk: Any
    """Risk level ``risk_iqr + risk_rnd`` (clipped to 1 for CVaR)."""
    weights: Any
    """Distortion weights ``(B, N)``."""
    iqr: Any
    rnd_error: Any
    risk_iqr: Any
    """The IQR band's risk level, or the fixed parameter without ``use_iqr``."""
    risk_rnd: Any
    """``tanh(rnd_error)`` with ``use_rnd``, else 0."""


@dataclass(frozen=True, kw_only=True)
class RiskModel:
    """The settings of HuRiPPO's risk machinery, checked when built (ValueError naming the first bad one).

    HuRiPPO builds it from its keyword arguments (:meth:`from_arguments`; ``HuRiPPO(...).risk_model``),
    saves its fields as attributes of the same names and rebuilds it from them (:meth:`from_attributes`)
    when loaded. It can also be built from every field.

    :param distributional: quantile critic; ``False`` is PPO's scalar critic, with no risk at all
    :param distortion: ``"wang"`` or ``"cvar"`` (unused by a scalar critic)
    :param use_iqr: the risk level comes from the IQR band of the atoms, else it is the fixed parameter
    :param use_rnd: ``tanh`` of the RND novelty of the critic state is added to the risk level
    :param n_quantiles: critic atoms ``N`` (>= 2); 1 for a scalar critic
    :param wang_beta: the fixed Wang ``beta`` (0: neutral, > 0: averse, < 0: seeking)
    :param cvar_alpha: the fixed CVaR level in ``(0, 1]`` (1: neutral)
    :param iqr_thresholds: ``(t_min, t_max)`` of the IQR band, in units of the (normalized) return; with
        the percentile band, the thresholds estimated so far (the given ones until the first rollout)
    :param iqr_risk_levels: the risk level below, within and above the band
    :param iqr_band: ``"absolute"``: ``iqr_thresholds`` are fixed (the paper's band as printed);
        ``"percentile"``: they are the ``iqr_percentiles`` of the per-state IQR of each rollout, smoothed
        over rollouts (:meth:`with_band_from`), so the band does not depend on the scale of the return
    :param iqr_percentiles: ``(p_min, p_max)`` in ``[0, 100]``, the percentiles of the percentile band
    :param iqr_band_smoothing: weight of a new rollout in the percentile band's exponential average, in
        ``(0, 1]`` (1: each rollout's own percentiles)
    :param td_level: the risk level a TD error of the advantages values its two states at
        (``sb3_huri.common.risk_gae``): ``"state"``, each at its own; ``"step"``, both at the level of the
        state the step starts from (a quantile critic only)
    """

    distributional: bool
    distortion: str
    use_iqr: bool
    use_rnd: bool
    n_quantiles: int
    wang_beta: float
    cvar_alpha: float
    iqr_thresholds: tuple[float, float]
    iqr_risk_levels: tuple[float, float, float]
    iqr_band: str = "absolute"
    iqr_percentiles: tuple[float, float] = (30.0, 70.0)
    iqr_band_smoothing: float = 0.5
    td_level: str = "state"

    def __post_init__(self) -> None:
        """Check every setting; store the numbers as floats and the sequences as tuples (a loaded model's
        are lists), so that equal settings give equal models."""
        if self.distortion not in DISTORTIONS:
            raise ValueError(f"Unknown distortion {self.distortion!r}: expected one of {list(DISTORTIONS)}")
        if self.iqr_band not in IQR_BANDS:
            raise ValueError(f"Unknown iqr_band {self.iqr_band!r}: expected one of {list(IQR_BANDS)}")
        if self.td_level not in TD_LEVELS:
            raise ValueError(f"Unknown td_level {self.td_level!r}: expected one of {list(TD_LEVELS)}")
        for name in ("distributional", "use_iqr", "use_rnd"):
            if not isinstance(getattr(self, name), bool | np.bool_):
                raise ValueError(f"{name} must be True or False, got {getattr(self, name)!r}")
            object.__setattr__(self, name, bool(getattr(self, name)))
        normalized = dict(
            wang_beta=_number("wang_beta", self.wang_beta, math.isfinite, "a finite number"),
            cvar_alpha=_number("cvar_alpha", self.cvar_alpha, lambda v: 0.0 < v <= 1.0, "in (0, 1]"),
            iqr_thresholds=_numbers(
                "iqr_thresholds", self.iqr_thresholds, 2, lambda v: 0.0 <= v[0] <= v[1],
                "(t_min, t_max) with 0 <= t_min <= t_max",
            ),
            iqr_risk_levels=_numbers(
                "iqr_risk_levels", self.iqr_risk_levels, 3, lambda v: True, "3 numbers (below, within, above)"
            ),
            iqr_percentiles=_numbers(
                "iqr_percentiles", self.iqr_percentiles, 2, lambda v: 0.0 <= v[0] <= v[1] <= 100.0,
                "(p_min, p_max) with 0 <= p_min <= p_max <= 100",
            ),
            iqr_band_smoothing=_number(
                "iqr_band_smoothing", self.iqr_band_smoothing, lambda v: 0.0 < v <= 1.0, "in (0, 1]"
            ),
        )  # fmt: skip
        for name, value in normalized.items():
            object.__setattr__(self, name, value)
        if self.distributional:
            if not (isinstance(self.n_quantiles, int | np.integer) and self.n_quantiles >= 2):
                raise ValueError(f"n_quantiles must be an integer >= 2, got {self.n_quantiles!r}")
        elif self.use_iqr or self.use_rnd or self.n_quantiles != 1 or self.td_level != "state":
            raise ValueError(
                "a scalar critic (distributional=False) takes no risk: use_iqr and use_rnd must be False, "
                f"n_quantiles 1 and td_level 'state', got use_iqr={self.use_iqr!r}, "
                f"use_rnd={self.use_rnd!r}, n_quantiles={self.n_quantiles!r}, td_level={self.td_level!r}"
            )
        object.__setattr__(self, "n_quantiles", int(self.n_quantiles))

    @classmethod
    def from_arguments(
        cls,
        method: str,
        *,
        n_quantiles: int | None,
        distortion: str | None,
        use_iqr: bool | None,
        use_rnd: bool | None,
        wang_beta: float,
        cvar_alpha: float,
        iqr_thresholds: tuple[float, float],
        iqr_risk_levels: tuple[float, float, float] | None,
        iqr_band: str | None = None,
        iqr_percentiles: tuple[float, float] = (30.0, 70.0),
        iqr_band_smoothing: float = 0.5,
        td_level: str | None = None,
    ) -> "RiskModel":
        """The model HuRiPPO's risk arguments describe (all of them: their defaults are HuRiPPO's): the
        preset of ``method`` (``sb3_huri.huri.methods``) with the given settings overriding its own. ``None``
        takes the preset's (``distortion``, ``use_iqr``, ``use_rnd``, ``iqr_band``, ``td_level``), 64 atoms
        (``n_quantiles``; a scalar critic has 1) and the distortion's levels (``iqr_risk_levels``: Wang
        ``(-1, 0, 1)``, CVaR ``(1, 1, 0.5)``, paper A.8).

        :raises ValueError: for an unknown method or distortion, risk settings on the scalar critic of
            ``huri-baseline``, or any setting out of its range
        """
        if method not in METHODS:
            raise ValueError(f"Unknown method {method!r}: expected one of {list(METHODS)}")
        preset = METHODS[method]
        risk_settings = (distortion is not None, use_iqr, use_rnd, iqr_band, td_level)
        if not preset.distributional and any(risk_settings):
            raise ValueError(
                "distortion, use_iqr, use_rnd, iqr_band and td_level need a quantile critic: "
                f"method={method!r} has a scalar critic (choose one of "
                f"{[name for name, p in METHODS.items() if p.distributional]})"
            )
        overrides = dict(
            distortion=distortion, use_iqr=use_iqr, use_rnd=use_rnd, iqr_band=iqr_band, td_level=td_level
        )
        preset = replace(preset, **{key: value for key, value in overrides.items() if value is not None})
        if iqr_risk_levels is None:
            iqr_risk_levels = DEFAULT_IQR_RISK_LEVELS.get(preset.distortion, (0.0, 0.0, 0.0))
        if not preset.distributional:
            n_quantiles = 1
        return cls(
            distributional=preset.distributional,
            distortion=preset.distortion,
            use_iqr=preset.use_iqr,
            use_rnd=preset.use_rnd,
            n_quantiles=DEFAULT_N_QUANTILES if n_quantiles is None else n_quantiles,
            wang_beta=wang_beta,
            cvar_alpha=cvar_alpha,
            iqr_thresholds=iqr_thresholds,
            iqr_risk_levels=iqr_risk_levels,
            iqr_band=preset.iqr_band,
            iqr_percentiles=iqr_percentiles,
            iqr_band_smoothing=iqr_band_smoothing,
            td_level=preset.td_level,
        )

    @classmethod
    def from_attributes(cls, source: object) -> "RiskModel":
        """The model whose settings are the attributes of `source` with the fields' names (a HuRiPPO, also
        one just loaded: its attributes are the saved ones, or the values ``load`` was given)."""
        return cls(**{field.name: getattr(source, field.name) for field in fields(cls)})

    def settings(self) -> dict[str, Any]:
        """The fields by name: what HuRiPPO keeps as attributes (and saves)."""
        return asdict(self)

    @property
    def adapts_band(self) -> bool:
        """Whether each rollout moves the IQR band's thresholds (the percentile band, in use)."""
        return self.distributional and self.use_iqr and self.iqr_band == "percentile"

    def with_band_from(self, iqr: np.ndarray, first: bool) -> "RiskModel":
        """The model after a rollout whose states have the per-state IQRs `iqr`: with the percentile band,
        its thresholds move towards the rollout's ``iqr_percentiles`` by ``iqr_band_smoothing`` (`first`:
        they become the rollout's own); otherwise unchanged. Only a rollout moves them: evaluation and
        ``assess_risk`` read the band as it is.

        Percentiles of the IQR are equivariant with the return's scale, so the levels a state gets do not
        depend on it, unlike the absolute band's.
        """
        if not self.adapts_band or len(iqr) == 0:
            return self
        observed = np.percentile(np.asarray(iqr, dtype=np.float64), self.iqr_percentiles)
        if first:
            thresholds = observed
        else:
            weight = self.iqr_band_smoothing
            thresholds = (1.0 - weight) * np.asarray(self.iqr_thresholds) + weight * observed
        t_min = max(float(thresholds[0]), 0.0)
        return replace(self, iqr_thresholds=(t_min, max(float(thresholds[1]), t_min)))

    @property
    def fixed_level(self) -> float:
        """The risk level without ``use_iqr``: ``wang_beta`` or ``cvar_alpha``."""
        return self.wang_beta if self.distortion == "wang" else self.cvar_alpha

    @property
    def risk_neutral(self) -> bool:
        """Whether every state's value is the plain atom mean: a quantile critic at a fixed neutral level
        (Wang ``beta = 0`` or CVaR ``alpha = 1``) with neither the IQR band nor RND (``huri-neutral``)."""
        neutral_level = 0.0 if self.distortion == "wang" else 1.0
        fixed = not self.use_iqr and not self.use_rnd
        return self.distributional and fixed and self.fixed_level == neutral_level

    def assess(self, outputs: th.Tensor, rnd_error: th.Tensor | None) -> RiskReading:
        """Sort the atoms, then per state: IQR, risk level, distortion weights, distorted value ``V_beta``.

        ``risk = (the IQR band's level if use_iqr else the fixed level) + (tanh(rnd_error) if use_rnd)``
        (paper eqs. 10-11), clipped to 1 for CVaR; a scalar critic gets weight 1 on its single atom.

        :param outputs: critic outputs, shape ``(B, n_quantiles)``, in any order
        :param rnd_error: RND novelty per state ``(B,)``; ``None`` without RND (read as zeros)
        """
        atoms = sorted_atoms(outputs)
        iqr = interquartile_range(atoms)
        if rnd_error is None:
            rnd_error = th.zeros_like(iqr)
        zeros = th.zeros_like(iqr)
        if not self.distributional:
            return RiskReading(atoms, atoms[:, 0], zeros, th.ones_like(atoms), iqr, rnd_error, zeros, zeros)
        if self.use_iqr:
            risk_iqr = iqr_risk_level(iqr, self.iqr_thresholds, self.iqr_risk_levels)
        else:
            risk_iqr = th.full_like(iqr, self.fixed_level)
        risk_rnd = th.tanh(rnd_error) if self.use_rnd else zeros
        risk = risk_iqr + risk_rnd
        if self.distortion == "cvar":
            risk = th.clamp(risk, max=1.0)
        if self.risk_neutral:  # exactly uniform, where Phi(Phi^-1(tau)) would be uniform up to rounding
            weights = th.full_like(atoms, 1.0 / self.n_quantiles)
        else:
            weights = distortion_weights(self.distortion, risk, self.n_quantiles)
        value = (weights * atoms).sum(dim=-1)
        return RiskReading(atoms, value, risk, weights, iqr, rnd_error, risk_iqr, risk_rnd)

    def rollout_metrics(self, reading: RiskReading) -> dict[str, float]:
        """A rollout's risk statistics by logger key, from its reading in numpy (docs/huri.md, "Logged").

        The risk level and its parts, the mean IQR, the shares of states above / within / below the IQR
        band and, with RND, the mean novelty; with the Wang distortion also under the ``beta`` names of
        earlier logs (``WANG_LOG_KEYS``).
        """
        t_min, t_max = self.iqr_thresholds
        iqr = reading.iqr
        metrics = {
            "rollout/iqr_t_min": t_min,
            "rollout/iqr_t_max": t_max,
            "rollout/risk_mean": float(reading.risk.mean()),
            "rollout/risk_iqr_mean": float(reading.risk_iqr.mean()),
            "rollout/iqr_mean": float(iqr.mean()),
            "rollout/iqr_above_share": float((iqr > t_max).mean()),
            "rollout/iqr_within_share": float(((iqr >= t_min) & (iqr <= t_max)).mean()),
            "rollout/iqr_below_share": float((iqr < t_min).mean()),
        }
        if self.use_rnd:
            metrics["rollout/risk_rnd_mean"] = float(reading.risk_rnd.mean())
            metrics["rollout/rnd_error"] = float(reading.rnd_error.mean())
        if self.distortion == "wang":
            metrics.update({WANG_LOG_KEYS[key]: metrics[key] for key in WANG_LOG_KEYS if key in metrics})
        return metrics


def _number(name: str, value: Any, valid: Callable[[float], bool], allowed: str) -> float:
    """`value` as a float; ValueError naming `name` and what is `allowed` unless it is a number and valid."""
    try:
        number = float(value)
    except (TypeError, ValueError):
        number = math.nan
    if isinstance(value, bool | str) or math.isnan(number) or not valid(number):
        raise ValueError(f"{name} must be {allowed}, got {value!r}")
    return number


def _numbers(
    name: str, values: Any, count: int, valid: Callable[[tuple[float, ...]], bool], allowed: str
) -> tuple[float, ...]:
    """`values` as a tuple of `count` floats; ValueError naming `name` and what is `allowed` unless valid."""
    try:
        numbers = tuple(float(value) for value in values)
    except (TypeError, ValueError):
        numbers = ()
    malformed = isinstance(values, str) or len(numbers) != count or any(map(math.isnan, numbers))
    if malformed or not valid(numbers):
        raise ValueError(f"{name} must be {allowed}, got {values!r}")
    return numbers
