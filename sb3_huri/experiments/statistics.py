"""The interval estimates of every table the experiments write, in one place.

- `mean_ci`: a mean over independent units (seeds, robots) with its 95% Student's t interval;
- `wilson_interval`: a share observed over episodes (survival) with its 95% Wilson score interval;
- `paired_difference_interval`: the difference of two shares measured on the same robots, with Newcombe's
  hybrid score interval for paired proportions;
- `iqm`, `probability_of_improvement` and `stratified_bootstrap`: the interquartile mean over seeds and the
  probability that one method beats another, with percentile intervals from a bootstrap that resamples
  seeds within each task (the estimates of Agarwal et al. 2021, "Deep RL at the edge of the statistical
  precipice", as its library rliable computes them), for results over a few seeds.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np


def mean_ci(values: Sequence[float | None]) -> tuple[float, float, int]:
    """Mean, half width of its 95% confidence interval (Student's t; NaN below two values) and count of the
    finite ``values``; NaN mean when there are none."""
    from scipy.special import stdtrit  # on first use: importing scipy costs a command 0.2 s

    finite = np.asarray([v for v in values if v is not None and math.isfinite(v)], dtype=float)
    n = len(finite)
    if n == 0:
        return math.nan, math.nan, 0
    if n == 1:
        return float(finite[0]), math.nan, 1
    return float(finite.mean()), float(stdtrit(n - 1, 0.975) * finite.std(ddof=1) / math.sqrt(n)), n


def wilson_interval(share: float, n: int) -> tuple[float, float]:
    """The 95% Wilson score interval of a share (e.g. ``survive``) observed over ``n`` episodes: unlike the
    normal approximation it stays within [0, 1] and is not empty at a share of 0 or 1. SciPy's
    (``binomtest(...).proportion_ci(method="wilson")``) of the count ``share * n``, rounded to a whole
    number of episodes."""
    from scipy.stats import binomtest  # on first use: importing scipy.stats costs a command 0.3 s

    if n <= 0:
        raise ValueError(f"a share needs at least one episode, got n={n}")
    if not 0.0 <= share <= 1.0:
        raise ValueError(f"a share is in [0, 1], got {share}")
    interval = binomtest(round(share * n), n).proportion_ci(confidence_level=0.95, method="wilson")
    return float(interval.low), float(interval.high)


def paired_difference_interval(first: np.ndarray, second: np.ndarray) -> tuple[float, float, float]:
    """Difference of two survival shares measured on the same robots, ``mean(first) - mean(second)``, with
    its 95% interval: Newcombe's hybrid score interval for paired proportions (method 10 of his 1998 paper
    on paired data), built from each share's Wilson interval and the correlation of the pairs.

    ``first``, ``second``: (robots,) booleans, robot i's outcome under each agent. Pairing is what makes
    two agents on the same seeds comparable with few robots: only the robots on which they disagree move
    the difference. Unlike a t-interval on the per-robot differences it is not empty when they never
    disagree, and stays within [-1, 1].
    """
    first, second = np.asarray(first, dtype=bool), np.asarray(second, dtype=bool)
    if first.shape != second.shape or first.ndim != 1 or first.size == 0:
        raise ValueError(f"need two outcomes per robot, got shapes {first.shape} and {second.shape}")
    n = first.size
    both, only_first = np.sum(first & second), np.sum(first & ~second)
    only_second, neither = np.sum(~first & second), np.sum(~first & ~second)
    share_first, share_second = first.mean(), second.mean()
    low_first, high_first = wilson_interval(share_first, n)
    low_second, high_second = wilson_interval(share_second, n)
    margins = float(
        (both + only_first) * (only_second + neither) * (both + only_second) * (only_first + neither)
    )
    phi = (both * neither - only_first * only_second) / math.sqrt(margins) if margins > 0 else 0.0
    below = (share_first - low_first, high_second - share_second)
    above = (high_first - share_first, share_second - low_second)
    delta = math.sqrt(max(below[0] ** 2 - 2 * phi * below[0] * below[1] + below[1] ** 2, 0.0))
    epsilon = math.sqrt(max(above[0] ** 2 - 2 * phi * above[0] * above[1] + above[1] ** 2, 0.0))
    difference = float(share_first - share_second)
    return difference, max(difference - delta, -1.0), min(difference + epsilon, 1.0)


def iqm(values: Sequence[float] | np.ndarray) -> float:
    """The interquartile mean: the mean of `values` without the lowest and highest ``floor(n / 4)`` of them,
    as rliable computes it (``scipy.stats.trim_mean(values, 0.25)``): the middle half when ``n`` is a
    multiple of 4, the middle three of five. Less moved by one outlying seed than the mean, less noisy than
    the median. ValueError for no values."""
    ordered = np.sort(np.asarray(values, dtype=float).ravel())
    if ordered.size == 0:
        raise ValueError("the interquartile mean of no values")
    cut = ordered.size // 4
    return float(ordered[cut : ordered.size - cut].mean())


def probability_of_improvement(first: Sequence[float], second: Sequence[float]) -> float:
    """P(X > Y) for X drawn from `first` and Y from `second` (each, e.g., one method's per-seed returns),
    ties counting half: the share of all ``len(first) * len(second)`` pairs in which `first` wins, rliable's
    probability of improvement on one task (the Mann-Whitney U statistic over the number of pairs)."""
    x, y = np.asarray(first, dtype=float)[:, None], np.asarray(second, dtype=float)[None, :]
    if x.size == 0 or y.size == 0:
        raise ValueError("the probability of improvement needs values of both methods")
    return float(np.mean((x > y) + 0.5 * (x == y)))


Strata = Sequence[Sequence[np.ndarray]]
"""Per stratum (task), the samples to resample (per method, its per-seed scores)."""


def stratified_bootstrap(
    strata: Strata,
    statistic: Callable[[Strata], float],
    *,
    resamples: int = 2000,
    confidence: float = 0.95,
    seed: int = 0,
) -> tuple[float, float]:
    """The percentile bootstrap interval of ``statistic(strata)``: each sample of each stratum (a method's
    seeds on a task) resampled with replacement to its own size, independently of the others, so every
    resample keeps each task's number of seeds per method (rliable's ``StratifiedIndependentBootstrap``);
    `resamples` of them drawn by numpy's Generator seeded `seed` (the same interval each time the same data
    is reported). ValueError for an empty sample."""
    samples = [[np.asarray(sample, dtype=float) for sample in stratum] for stratum in strata]
    if not samples or any(sample.size == 0 for stratum in samples for sample in stratum):
        raise ValueError("a stratified bootstrap needs at least one value in every sample")
    rng = np.random.default_rng(seed)
    draws = np.empty(resamples)
    for r in range(resamples):
        draws[r] = statistic(
            [[sample[rng.integers(0, sample.size, sample.size)] for sample in stratum] for stratum in samples]
        )
    tail = 50.0 * (1.0 - confidence)
    low, high = np.percentile(draws, [tail, 100.0 - tail])
    return float(low), float(high)


def iqm_interval(values: Sequence[float], **bootstrap: Any) -> tuple[float, float, float]:
    """The IQM of one task's per-seed `values` and its 95% stratified bootstrap interval (one stratum)."""
    low, high = stratified_bootstrap([[np.asarray(values)]], lambda strata: iqm(strata[0][0]), **bootstrap)
    return iqm(values), low, high


def improvement_interval(
    pairs: Sequence[tuple[Sequence[float], Sequence[float]]], **bootstrap: Any
) -> tuple[float, float, float]:
    """The probability that X beats Y averaged over tasks (`pairs`: per task, X's and Y's per-seed scores),
    as rliable aggregates it, with its 95% stratified bootstrap interval (each method's seeds resampled
    within each task)."""

    def average(strata: Strata) -> float:
        return float(np.mean([probability_of_improvement(x, y) for x, y in strata]))

    strata = [[np.asarray(x), np.asarray(y)] for x, y in pairs]
    low, high = stratified_bootstrap(strata, average, **bootstrap)
    return average(strata), low, high
