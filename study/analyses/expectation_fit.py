"""Which reading of the expectation loss (eq. 5) lets the critic fit the spread of a known distribution.

Free atoms (no network) are fitted by Adam to target atoms drawn from a known normal distribution, with the
critic's loss ``energy_distance + coef * expectation_loss`` at a fixed Wang ``beta``, and compared with the
true mean and standard deviation. The ``"distorted"`` reading (eq. 5 as printed: the predicted mean against
its own distorted mean) is zero only for a point mass, so it shrinks the fitted spread as ``beta`` and the
coefficient grow; the ``"target"`` reading (the predicted mean against the target atoms' mean) does not
(``sb3_huri.common.expectation``). ``study.scripts.expectation_loss`` prints the table.
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence

import torch as th

from sb3_huri.common.distortion import wang_weights
from sb3_huri.common.energy import energy_distance
from sb3_huri.common.expectation import EXPECTATION_LOSSES, expectation_loss

KNOWN_MEAN, KNOWN_STD = 2.0, 1.5
"""The known distribution the atoms are fitted to: N(2, 1.5^2)."""


def fit_known_distribution(
    reading: str,
    beta: float,
    coef: float,
    *,
    mean: float = KNOWN_MEAN,
    std: float = KNOWN_STD,
    n_quantiles: int = 64,
    batch: int = 64,
    steps: int = 2000,
    seed: int = 0,
) -> tuple[float, float]:
    """Fit ``n_quantiles`` free atoms to samples of ``N(mean, std^2)``; returns the fitted (mean, std).

    Each step draws ``batch`` states' target atoms (``n_quantiles`` samples each), as a critic sees one
    sampled return distribution per state; all states share the prediction.
    """
    generator = th.Generator().manual_seed(seed)
    atoms = th.zeros(n_quantiles, requires_grad=True)
    optimizer = th.optim.Adam([atoms], lr=0.02)
    weights = wang_weights(th.full((batch,), beta), n_quantiles)
    for step in range(steps):
        if step == steps // 2:  # a smaller step for the second half, for a precise end point
            for group in optimizer.param_groups:
                group["lr"] = 0.005
        targets = mean + std * th.randn(batch, n_quantiles, generator=generator)
        predicted = th.sort(atoms.expand(batch, -1), dim=-1).values
        loss = energy_distance(predicted, targets).mean()
        loss = loss + coef * expectation_loss(predicted, targets, weights, reading)
        optimizer.zero_grad()
        loss.backward()
        optimizer.step()
    fitted = atoms.detach()
    # The atoms of N(mean, std^2) at levels (i + 0.5) / N have a std a little below std: compare like to like.
    levels = (th.arange(n_quantiles) + 0.5) / n_quantiles
    ideal_std = float((std * th.special.ndtri(levels)).std(unbiased=False))
    return float(fitted.mean()), float(fitted.std(unbiased=False)) / ideal_std * std


def spread_table(betas: Sequence[float], coefs: Sequence[float], seeds: int) -> Iterator[str]:
    """Fitted std / true std and fitted mean for every reading, ``beta`` and coefficient, averaged over
    ``seeds`` fits: the lines of a markdown table, each row yielded as soon as it is fitted."""
    yield from ("| reading | beta | coef | fitted std / true std | fitted mean |", "|---|---|---|---|---|")
    for reading in EXPECTATION_LOSSES:
        for beta in betas:
            for coef in coefs:
                fits = [fit_known_distribution(reading, beta, coef, seed=seed) for seed in range(seeds)]
                fitted_mean = sum(f[0] for f in fits) / len(fits)
                ratio = sum(f[1] for f in fits) / len(fits) / KNOWN_STD
                yield f"| {reading} | {beta:g} | {coef:g} | {ratio:.3f} | {fitted_mean:.3f} |"
