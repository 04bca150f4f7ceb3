"""Energy distance between empirical one-dimensional distributions, the quantile loss of HuRi (eq. 4)."""

import torch as th
from torch.nn import functional as F


def _sum_abs_differences_sorted(ordered: th.Tensor) -> th.Tensor:
    """``sum_{i, j} |s_i - s_j|`` over all ordered pairs of sorted samples: ``2 sum_k s_(k) (2k - n - 1)``."""
    n = ordered.shape[-1]
    coefficients = th.arange(1 - n, n, 2, dtype=ordered.dtype, device=ordered.device)
    return 2.0 * (ordered * coefficients).sum(dim=-1)


def energy_distance(x: th.Tensor, y: th.Tensor, presorted: bool = False) -> th.Tensor:
    """Energy distance ``2 E|X - Y| - E|X - X'| - E|Y - Y'|`` between uniform mixtures of Diracs.

    All pairs are counted, including ``i = j`` (whose differences are zero), as in the paper's eq. (4) and
    ``scipy.stats.energy_distance``, which returns the *square root* of this quantity.
    Computed in ``O((N + M) log M)`` from sorted samples instead of the ``N x M`` pairwise tensors: with
    ``y`` sorted and ``S_k`` the sum of its ``k`` smallest atoms, ``sum_j |x_i - y_j| =
    x_i (2 k_i - M) + S_M - 2 S_(k_i)`` where ``k_i`` counts the atoms of ``y`` below ``x_i``.
    Differentiable in both arguments.

    :param x: atoms of shape ``(..., N)`` (e.g. the predicted quantiles), in any order
    :param y: atoms of shape ``(..., M)`` (e.g. the target atoms), in any order
    :param presorted: both ``x`` and ``y`` are already sorted in increasing order along the last axis
        (the two sorts are skipped; a training step that sorts its atoms anyway saves them)
    :return: the energy distance per leading index, shape ``(...)``
    """
    n, m = x.shape[-1], y.shape[-1]
    # The distance is translation invariant: centring keeps the sums' cancellations accurate in float32.
    center = 0.5 * (x.mean(dim=-1, keepdim=True) + y.mean(dim=-1, keepdim=True)).detach()
    x, y = x - center, y - center  # the same shift for a row keeps its order
    if not presorted:
        x, y = th.sort(x, dim=-1).values, th.sort(y, dim=-1).values
    below = th.searchsorted(y.detach().contiguous(), x.detach().contiguous())
    prefix_sums = F.pad(th.cumsum(y, dim=-1), (1, 0))
    cross = x * (2 * below - m) + prefix_sums[..., -1:] - 2.0 * th.gather(prefix_sums, -1, below)
    within_x, within_y = _sum_abs_differences_sorted(x), _sum_abs_differences_sorted(y)
    return 2.0 * cross.sum(dim=-1) / (n * m) - within_x / n**2 - within_y / m**2
