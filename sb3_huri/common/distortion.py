"""Distortion risk measures as weights over the sorted atoms of a quantile distribution.

A distortion function ``g: [0, 1] -> [0, 1]`` (increasing, ``g(0) = 0``, ``g(1) = 1``) re-weights the
probability levels of a return distribution. For ``N`` equally weighted atoms sorted in increasing order,
the distorted expectation is ``sum_i w_i theta_(i)`` with ``w_i = g(i / N) - g((i - 1) / N)``: the weights
are non-negative and sum to one, so the distorted value is a convex combination of the atoms.
"""

import torch as th

DISTORTIONS = ("wang", "cvar")


def _levels(n_quantiles: int, like: th.Tensor) -> th.Tensor:
    """The probability levels ``0, 1/N, ..., 1`` on the device and dtype of ``like``."""
    return th.linspace(0.0, 1.0, n_quantiles + 1, dtype=like.dtype, device=like.device)


def wang_weights(beta: th.Tensor, n_quantiles: int) -> th.Tensor:
    """Wang distortion ``g(tau) = Phi(Phi^-1(tau) + beta)`` as atom weights.

    ``beta > 0`` moves weight to the low (bad) atoms, a risk-averse value below the mean; ``beta < 0`` is
    risk-seeking; ``beta = 0`` gives uniform weights, the plain mean.

    :param beta: risk parameter per state, shape ``(...)``
    :param n_quantiles: number of atoms ``N``
    :return: weights of shape ``(..., N)`` for the atoms sorted in increasing order
    """
    beta = th.as_tensor(beta)
    # ndtri(0) = -inf and ndtri(1) = +inf, so g(0) = 0 and g(1) = 1 exactly for any finite beta.
    cdf = th.special.ndtr(th.special.ndtri(_levels(n_quantiles, beta)) + beta.unsqueeze(-1))
    return cdf[..., 1:] - cdf[..., :-1]


def cvar_weights(alpha: th.Tensor, n_quantiles: int) -> th.Tensor:
    """Conditional value at risk ``g(tau) = min(tau / alpha, 1)`` as atom weights.

    The distorted value is the mean of the worst ``alpha`` fraction of outcomes; ``alpha = 1`` is the mean.

    :param alpha: tail fraction per state in ``(0, 1]``, shape ``(...)``
    :param n_quantiles: number of atoms ``N``
    :return: weights of shape ``(..., N)`` for the atoms sorted in increasing order
    """
    alpha = th.as_tensor(alpha)
    cdf = th.clamp(_levels(n_quantiles, alpha) / alpha.unsqueeze(-1), max=1.0)
    return cdf[..., 1:] - cdf[..., :-1]


def distortion_weights(distortion: str, risk: th.Tensor, n_quantiles: int) -> th.Tensor:
    """Atom weights of a distortion: ``"wang"`` with ``beta = risk``, ``"cvar"`` with ``alpha = risk``.

    CVaR is only defined for ``alpha`` in ``(0, 1]``: larger values (e.g. a CVaR level raised by an RND bonus)
    are clipped to 1, the risk-neutral mean.
    """
    if distortion == "wang":
        return wang_weights(risk, n_quantiles)
    if distortion == "cvar":
        return cvar_weights(th.clamp(risk, min=1e-6, max=1.0), n_quantiles)
    raise ValueError(f"Unknown distortion {distortion!r}: expected one of {DISTORTIONS}")
