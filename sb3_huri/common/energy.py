"""Energy distance between empirical one-dimensional distributions, the quantile loss of HuRi (eq. 4)."""

import functools
from typing import Any

import torch as th
from torch.nn import functional as F

from sb3_huri.common.quantiles import sorted_atoms


@functools.lru_cache(maxsize=32)
def _slope_terms(n: int, m: int, dtype: th.dtype, device: th.device) -> tuple[float, th.Tensor]:
    """``(4 / (n m), offset)`` with which the slopes of the atoms of a sample of `n` against one of `m` are
    ``count * 4 / (n m) - offset``: ``offset_k = 2 / n + 2 (2k - n - 1) / n^2`` for the ranks ``k = 1..n``."""
    ranks = th.arange(1 - n, n, 2, dtype=dtype, device=device)  # 2k - n - 1
    return 4.0 / (n * m), 2.0 / n + ranks * (2.0 / n**2)


class _SortedEnergyDistance(th.autograd.Function):
    """The energy distance of sorted samples ``x (..., n)`` and ``y (..., m)``, its gradient in closed form.

    The loss is piecewise linear in the atoms, with slopes ``d/dx_(k) = 2 (2 b_k - m) / (n m) -
    2 (2k - n - 1) / n^2`` (``b_k``: the atoms of ``y`` below ``x_(k)``) and ``d/dy_(k) =
    2 (2 a_k - n) / (n m) - 2 (2k - m - 1) / m^2`` (``a_k``: the atoms of ``x`` at or below ``y_(k)``; at a
    tie the two counts split the pair, whose distance is 0). Its value is ``sum_k x_(k) d/dx_(k)`` plus what
    depends on ``y`` alone given the counts ``b``: ``2 S_m / m - 4 / (n m) sum_k S_(b_k) - 2 sum_k y_(k)
    (2k - m - 1) / m^2``, with ``S_j`` the sum of the ``j`` smallest atoms of ``y``. Forward and backward
    are then a few tensor operations each, one search of ``x`` in ``y`` among them, where autograd records
    some twenty per minibatch of every update (and ``y``'s slopes are only counted when ``y`` needs them).
    """

    @staticmethod
    def forward(ctx: Any, x: th.Tensor, y: th.Tensor) -> th.Tensor:
        n, m = x.shape[-1], y.shape[-1]
        # The distance is translation invariant: a shift to the middle of `y` keeps the sums' cancellations
        # accurate in float32.
        center = y[..., m // 2 : m // 2 + 1]
        x, y = x - center, y - center
        scale_x, offset_x = _slope_terms(n, m, x.dtype, x.device)
        below = th.searchsorted(y, x)  # for each x, the atoms of y strictly below it
        slope_x = below.to(x.dtype) * scale_x - offset_x
        prefix_sums = F.pad(th.cumsum(y, dim=-1), (1, 0))
        _, offset_y = _slope_terms(m, n, y.dtype, y.device)  # 2 / m + 2 (2k - m - 1) / m^2
        ctx.save_for_backward(slope_x, x, y)
        # 2 S_m / m - 2 sum_k y_(k) (2k - m - 1) / m^2 = sum_k y_(k) (4 / m - offset_y_k)
        return (
            (x * slope_x).sum(dim=-1)
            + (y * (4.0 / m - offset_y)).sum(dim=-1)
            - th.gather(prefix_sums, -1, below).sum(dim=-1) * scale_x
        )

    @staticmethod
    def backward(ctx: Any, grad: th.Tensor) -> tuple[th.Tensor | None, th.Tensor | None]:
        slope_x, x, y = ctx.saved_tensors
        grad = grad.unsqueeze(-1)
        grad_y = None
        if ctx.needs_input_grad[1]:
            scale_y, offset_y = _slope_terms(y.shape[-1], x.shape[-1], y.dtype, y.device)
            at_or_below = th.searchsorted(x, y, right=True)  # for each y, the atoms of x at or below it
            grad_y = grad * (at_or_below.to(y.dtype) * scale_y - offset_y)
        return grad * slope_x, grad_y


def energy_distance(x: th.Tensor, y: th.Tensor, presorted: bool = False) -> th.Tensor:
    """Energy distance ``2 E|X - Y| - E|X - X'| - E|Y - Y'|`` between uniform mixtures of Diracs.

    All pairs are counted, including ``i = j`` (whose differences are zero), as in the paper's eq. (4) and
    ``scipy.stats.energy_distance``, which returns the *square root* of this quantity.
    Computed in ``O((N + M) log(N + M))`` from sorted samples instead of the ``N x M`` pairwise tensors:
    each atom's slope follows from its rank and the count of the other sample's atoms below it, and the
    value from the slopes and the prefix sums of ``y`` (``_SortedEnergyDistance``). Differentiable in both
    arguments (a subgradient where atoms tie).

    :param x: atoms of shape ``(..., N)`` (e.g. the predicted quantiles), in any order
    :param y: atoms of shape ``(..., M)`` (e.g. the target atoms), in any order
    :param presorted: both ``x`` and ``y`` are already sorted in increasing order along the last axis
        (the two sorts are skipped; a training step that sorts its atoms anyway saves them)
    :return: the energy distance per leading index, shape ``(...)``
    """
    if not presorted:
        x, y = sorted_atoms(x), sorted_atoms(y)
    return _SortedEnergyDistance.apply(x, y)
