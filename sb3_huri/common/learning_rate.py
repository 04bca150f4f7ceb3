"""The learning rate of a PPO update: the KL-adaptive rule of legged-robot PPO trainers, and the rates of an
optimizer whose critic has a parameter group of its own.

The KL-adaptive rule keeps each policy step near a desired KL divergence from the rollout's policy: after a
minibatch whose approximate KL is above twice the desired one the rate is divided by 1.5, below half of it
multiplied by 1.5, within bounds (docs/huri.md, "KL control"). A trust region on a narrow action noise
needs a small actor rate, which would stop the critic learning if it were shared: the critic's parameter
group (named ``"critic"``) may then follow a rate of its own.
"""

import torch as th
from stable_baselines3.common.utils import update_learning_rate


def kl_adaptive_rate(
    learning_rate: float, approx_kl: float, desired_kl: float, bounds: tuple[float, float]
) -> float:
    """The rate after a minibatch with approximate KL `approx_kl`: smaller when the policy moved too far
    (``> 2 * desired_kl``), larger when it moved too little (``< desired_kl / 2``), within ``(low, high)``
    `bounds`; a KL of 0 (the update's first minibatch) leaves it."""
    low, high = bounds
    if approx_kl > 2.0 * desired_kl:
        return max(learning_rate / 1.5, low)
    if 0.0 < approx_kl < 0.5 * desired_kl:
        return min(learning_rate * 1.5, high)
    return learning_rate


def set_learning_rates(
    optimizer: th.optim.Optimizer, learning_rate: float, critic_learning_rate: float | None = None
) -> None:
    """Set `learning_rate` on every parameter group, or with `critic_learning_rate` on the group named
    ``"critic"`` and `learning_rate` on the others."""
    if critic_learning_rate is None:
        update_learning_rate(optimizer, learning_rate)
        return
    for group in optimizer.param_groups:
        group["lr"] = critic_learning_rate if group.get("name") == "critic" else learning_rate
