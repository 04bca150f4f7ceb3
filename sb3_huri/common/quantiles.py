"""Reading quantile levels and spread off the atoms of a quantile critic."""

import math

import numpy as np
import torch as th

NUMPY_ORDER_ROWS = 256
"""From this many rows on, a CPU batch of atoms is ordered by numpy (``sorted_atoms``)."""


def sorted_atoms(atoms: th.Tensor) -> th.Tensor:
    """``atoms`` sorted in increasing order along the last axis, differentiable: each atom keeps its gradient.

    ``torch.sort`` is slow on the CPU for many short rows: a (4096, 64) batch takes it 11 ms, where numpy's
    ``argsort`` and a ``gather`` take 0.9 ms. A CPU batch of at least ``NUMPY_ORDER_ROWS`` rows is ordered
    by numpy; the sorted values are the same (only atoms that tie exactly may trade their gradients).
    """
    if atoms.device.type != "cpu" or atoms.numel() < NUMPY_ORDER_ROWS * atoms.shape[-1]:
        return th.sort(atoms, dim=-1).values
    order = np.argsort(atoms.detach().numpy(), axis=-1)
    return th.gather(atoms, -1, th.from_numpy(order))


def interpolated_quantile(sorted_atoms: th.Tensor, level: float) -> th.Tensor:
    """Quantile ``F^-1(level)`` of ``N`` sorted atoms, linearly interpolated between atom midpoints.

    Atom ``i`` (0-based) of a quantile critic estimates the quantile at ``tau_i = (i + 0.5) / N``
    (QR-DQN's midpoints); between midpoints we interpolate linearly and beyond them we take the end atom.
    This is ``numpy.quantile(..., method="hazen")``.

    :param sorted_atoms: atoms sorted in increasing order along the last axis, shape ``(..., N)``
    :param level: probability level in ``[0, 1]``
    :return: shape ``(...)``
    """
    n = sorted_atoms.shape[-1]
    position = min(max(level * n - 0.5, 0.0), n - 1.0)
    lower = math.floor(position)
    upper = min(lower + 1, n - 1)
    fraction = position - lower
    return sorted_atoms[..., lower] * (1.0 - fraction) + sorted_atoms[..., upper] * fraction


def interquartile_range(sorted_atoms: th.Tensor) -> th.Tensor:
    """``IQR = Q(0.75) - Q(0.25)`` (paper eq. 8), the intrinsic uncertainty of the return distribution."""
    return interpolated_quantile(sorted_atoms, 0.75) - interpolated_quantile(sorted_atoms, 0.25)


def iqr_risk_level(
    iqr: th.Tensor,
    thresholds: tuple[float, float],
    levels: tuple[float, float, float],
) -> th.Tensor:
    """Risk parameter from the IQR band (paper Algorithm 1, lines 12-19).

    :param iqr: interquartile range per state
    :param thresholds: ``(t_min, t_max)``
    :param levels: risk parameter for ``IQR < t_min``, ``t_min <= IQR <= t_max`` and ``IQR > t_max``;
        ``(-1, 0, 1)`` for the Wang distortion (risk-seeking, neutral, averse)
    """
    t_min, t_max = thresholds
    below, within, above = (th.tensor(level, dtype=iqr.dtype, device=iqr.device) for level in levels)
    return th.where(iqr > t_max, above, th.where(iqr < t_min, below, within))
