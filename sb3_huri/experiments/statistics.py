"""The interval estimates of every table the experiments write, in one place.

- `mean_ci`: a mean over independent units (seeds, robots) with its 95% Student's t interval;
- `wilson_interval`: a share observed over episodes (survival) with its 95% Wilson score interval;
- `paired_difference_interval`: the difference of two shares measured on the same robots, with Newcombe's
  hybrid score interval for paired proportions.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

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
