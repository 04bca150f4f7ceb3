"""The expectation loss of HuRi's critic (paper eq. 5), in the two readings the paper allows.

Eq. 5 is ``MSE(E_tau[Z_theta(tau)], E_tau[Z_theta(beta(tau))])``: the mean of the predicted distribution
against its own distorted mean. Read literally (``"distorted"``) it compares two functionals of the *same*
atoms, so its minimum is a distribution whose distorted mean equals its mean, i.e. (for ``beta != 0``) a
point mass: it also penalizes the spread of the prediction, and with the energy loss it shrinks the fitted
distribution (``study/scripts/expectation_loss.py``: 0.82 of the true standard deviation at ``beta = 1``
and coefficient 0.05). The paper's text describes the loss as the MSE "between the target expectation and
the expected ... after implementing the risk distortion", a loss against the *target*. The ``"target"``
reading matches the predicted mean to the mean of the target atoms, PPO's value loss on the critic's
expectation: it is zero in expectation at the true distribution, so it adds a direct signal on the first
moment without biasing the fitted spread. On Zerith1-v0 the printed reading walked better (docs/huri.md),
so it stays the algorithm's default.
"""

import torch as th
from torch.nn import functional as F

EXPECTATION_LOSSES = ("target", "distorted")


def expectation_loss(
    sorted_atoms: th.Tensor, target_atoms: th.Tensor, weights: th.Tensor, reading: str = "distorted"
) -> th.Tensor:
    """Mean squared error on the critic's expectation, averaged over states.

    :param sorted_atoms: predicted atoms sorted in increasing order, shape ``(B, N)``
    :param target_atoms: target atoms, shape ``(B, M)`` (order irrelevant)
    :param weights: distortion weights ``w(beta_s)`` over the sorted atoms, shape ``(B, N)``
    :param reading: ``"target"``: ``MSE(mean_i theta_i, mean_j target_j)``; ``"distorted"`` (eq. 5 as
        printed): ``MSE(mean_i theta_i, sum_i w_i theta_(i))``, gradient through both terms
    """
    mean = sorted_atoms.mean(dim=-1)
    if reading == "target":
        return F.mse_loss(mean, target_atoms.mean(dim=-1))
    if reading == "distorted":
        return F.mse_loss(mean, (weights * sorted_atoms).sum(dim=-1))
    raise ValueError(f"Unknown expectation loss {reading!r}: expected one of {EXPECTATION_LOSSES}")
