"""Energy distance between empirical one-dimensional distributions, the quantile loss of HuRi (eq. 4)."""

import torch as th


def _sum_abs_differences(samples: th.Tensor) -> th.Tensor:
    """``sum_{i, j} |s_i - s_j|`` over all ordered pairs of the last axis, in ``O(N log N)``.

    For sorted samples ``s_(1) <= ... <= s_(n)`` the sum equals ``2 sum_k s_(k) (2k - n - 1)``.
    """
    n = samples.shape[-1]
    ordered = th.sort(samples, dim=-1).values
    coefficients = th.arange(1 - n, n, 2, dtype=samples.dtype, device=samples.device)
    return 2.0 * (ordered * coefficients).sum(dim=-1)


def energy_distance(x: th.Tensor, y: th.Tensor) -> th.Tensor:
    """Energy distance ``2 E|X - Y| - E|X - X'| - E|Y - Y'|`` between uniform mixtures of Diracs.

    All pairs are counted, including ``i = j`` (whose differences are zero), as in the paper's eq. (4) and
    ``scipy.stats.energy_distance``, which returns the *square root* of this quantity. Computed from sorted
    samples instead of the ``N x M`` pairwise tensor: the cross term follows from
    ``sum|Z - Z'| = sum|X - X'| + sum|Y - Y'| + 2 sum|X - Y|`` for the pooled sample ``Z``.
    Differentiable in both arguments (gradients flow through the sort).

    :param x: atoms of shape ``(..., N)`` (e.g. the predicted quantiles)
    :param y: atoms of shape ``(..., M)`` (e.g. the target atoms)
    :return: the energy distance per leading index, shape ``(...)``
    """
    n, m = x.shape[-1], y.shape[-1]
    # The distance is translation invariant: centring keeps the sorted-sum cancellations accurate in float32.
    center = th.cat((x, y), dim=-1).mean(dim=-1, keepdim=True).detach()
    x, y = x - center, y - center
    within_x = _sum_abs_differences(x)
    within_y = _sum_abs_differences(y)
    cross = 0.5 * (_sum_abs_differences(th.cat((x, y), dim=-1)) - within_x - within_y)
    return 2.0 * cross / (n * m) - within_x / n**2 - within_y / m**2
