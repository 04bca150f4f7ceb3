"""HuRiPPO's hyperparameters checked and resolved: everything but the risk settings, which `RiskModel` checks.

A hyperparameter is checked where it is set: at construction, and again after ``load``, whose keyword
arguments may replace the saved values (``RULES``, :func:`check_hyperparameters`). The minibatch size is
resolved against the rollout's size and the action space checked once the env is known; the arguments
``policy_kwargs`` may carry too (``n_quantiles``, ``rnd_kwargs``) are reconciled with the model's own; and an
env that does not normalize its rewards is warned about before learning, because the absolute IQR band is in
units of the normalized return. A ValueError always names the first invalid hyperparameter and what it may
be, so that a wrong preset fails at once rather than hours into a run.
"""

import warnings
from collections.abc import Callable
from typing import Any

from gymnasium import spaces
from gymnasium.wrappers import NormalizeReward
from stable_baselines3.common.vec_env import VecEnv, unwrap_vec_normalize

from sb3_huri.common.expectation import EXPECTATION_LOSSES
from sb3_huri.huri.risk import RiskModel

SUPPORTED_ACTION_SPACES = (spaces.Box, spaces.Discrete, spaces.MultiDiscrete, spaces.MultiBinary)


class UnnormalizedRewardWarning(UserWarning):
    """HuRiPPO learns on an env whose rewards are not normalized, so the IQR thresholds may be meaningless."""


RULES: dict[str, tuple[Callable[[Any], bool], str]] = {
    "n_steps": (lambda v: v >= 1, "an integer >= 1"),
    "n_epochs": (lambda v: v >= 1, "an integer >= 1"),
    "n_minibatches": (lambda v: v is None or v >= 1, "None or an integer >= 1"),
    "gamma": (lambda v: 0.0 <= v <= 1.0, "in [0, 1]"),
    "gae_lambda": (lambda v: 0.0 <= v <= 1.0, "in [0, 1]"),
    "sr_lambda": (lambda v: 0.0 <= v <= 1.0, "in [0, 1]"),
    "quantile_coef": (lambda v: v >= 0.0, ">= 0"),
    "expectation_coef": (lambda v: v >= 0.0, ">= 0"),
    "mirror_coef": (lambda v: v >= 0.0, ">= 0"),
    "expectation_loss": (lambda v: v in EXPECTATION_LOSSES, f"one of {EXPECTATION_LOSSES}"),
    "desired_kl": (lambda v: v is None or v > 0.0, "None or > 0"),
    "critic_learning_rate": (
        lambda v: v is None or callable(v) or (isinstance(v, int | float) and v > 0.0),
        "None, a float > 0 or a schedule",
    ),
}
"""Allowed values of the hyperparameters :func:`check_hyperparameters` checks, and how to say so."""


def check_hyperparameters(**values: Any) -> None:
    """Raise a ValueError naming the first invalid hyperparameter and its allowed values."""
    for name, value in values.items():
        valid, allowed = RULES[name]
        if not valid(value):
            raise ValueError(f"{name} must be {allowed}, got {value!r}")


def check_action_space(action_space: spaces.Space) -> None:
    """Raise a ValueError for an action space HuRiPPO cannot act in."""
    if not isinstance(action_space, SUPPORTED_ACTION_SPACES):
        raise ValueError(
            f"HuRiPPO does not support the action space {action_space}: "
            f"expected one of {[space.__name__ for space in SUPPORTED_ACTION_SPACES]}"
        )


DEFAULT_BATCH_SIZE = 64
"""The minibatch size when neither ``batch_size`` nor ``n_minibatches`` is given: SB3's PPO default."""


def resolve_batch_size(batch_size: int | None, n_minibatches: int | None, rollout_size: int) -> int:
    """The minibatch size: ``batch_size`` as PPO reads it, else the rollout split into ``n_minibatches``,
    else ``DEFAULT_BATCH_SIZE``; checked against the rollout as PPO checks it. ``batch_size`` is the primary
    knob: given, it wins over ``n_minibatches`` (as ``rl_zoo3 train --hyperparams batch_size:64`` overrides
    a preset that splits its rollouts).

    A minibatch size that does not divide the rollout gives a warning, as in PPO: each epoch then ends
    with a smaller minibatch (or, larger than the rollout, is one minibatch of the whole rollout).
    """
    if batch_size is None and n_minibatches is not None:
        if n_minibatches > rollout_size:
            raise ValueError(
                f"n_minibatches must be at most n_steps * n_envs = {rollout_size}, got {n_minibatches}"
            )
        return -(-rollout_size // n_minibatches)
    batch_size = DEFAULT_BATCH_SIZE if batch_size is None else batch_size
    if batch_size <= 1:
        raise ValueError(f"batch_size must be > 1 (normalized advantages need two samples), got {batch_size}")
    if batch_size > rollout_size:
        warnings.warn(
            f"batch_size={batch_size} is larger than the rollout, n_steps * n_envs = {rollout_size}: "
            f"each epoch is one minibatch of {rollout_size} samples",
            stacklevel=3,
        )
    elif rollout_size % batch_size:
        warnings.warn(
            f"batch_size={batch_size} does not divide the rollout size n_steps * n_envs = {rollout_size}: "
            f"each epoch ends with a minibatch of {rollout_size % batch_size} samples",
            stacklevel=3,
        )
    return batch_size


def agreeing(name: str, value: Any, policy_kwargs: dict[str, Any], default: Any) -> Any:
    """An argument ``policy_kwargs`` may carry too: the given value, else the carried one, else default."""
    carried = policy_kwargs.get(name)
    if value is not None and carried is not None and carried != value:
        raise ValueError(
            f"{name}={value!r} conflicts with policy_kwargs['{name}']={carried!r}: pass one of them"
        )
    return next((v for v in (value, carried) if v is not None), default)


def completed_policy_kwargs(
    policy_kwargs: dict[str, Any],
    risk_model: RiskModel,
    rnd_kwargs: dict[str, Any] | None,
    critic_param_group: bool,
    method: str,
) -> dict[str, Any]:
    """``policy_kwargs`` with the critic's width and the RND settings the risk model needs, so that a saved
    model rebuilds them, and the critic's own parameter group when it learns at its own rate.

    ``policy_kwargs`` may already hold ``n_quantiles`` (a ValueError if it is not the risk model's) and
    ``rnd_kwargs`` (kept over `rnd_kwargs`, as a loaded model's are); without RND, ``rnd_kwargs`` is None.
    """
    kwargs = dict(policy_kwargs)
    if critic_param_group:
        kwargs["critic_param_group"] = True  # the optimizer's second group: the critic's own rate
    n_quantiles = risk_model.n_quantiles
    if kwargs.setdefault("n_quantiles", n_quantiles) != n_quantiles:
        raise ValueError(
            f"policy_kwargs['n_quantiles']={kwargs['n_quantiles']} does not match the critic of "
            f"method={method!r} ({n_quantiles} atoms)"
        )
    carried = kwargs.get("rnd_kwargs")
    kwargs["rnd_kwargs"] = (carried if carried is not None else rnd_kwargs) if risk_model.use_rnd else None
    return kwargs


def normalizes_rewards(env: VecEnv) -> bool:
    """Whether the env scales its rewards: ``VecNormalize(norm_reward=True)`` or ``NormalizeReward``."""
    normalizer = unwrap_vec_normalize(env)
    if normalizer is not None and normalizer.norm_reward:
        return True
    try:
        return any(env.env_is_wrapped(NormalizeReward))
    except (AttributeError, NotImplementedError):
        return False


def warn_unless_rewards_normalized(env: VecEnv, iqr_thresholds: tuple[float, float]) -> None:
    """An :class:`UnnormalizedRewardWarning` (pointed at the caller of ``learn``) if `env` does not
    normalize its rewards, the units of the IQR band's `iqr_thresholds`."""
    if normalizes_rewards(env):
        return
    warnings.warn(
        f"HuRiPPO's IQR thresholds {iqr_thresholds} are in units of normalized "
        "returns, but the env does not normalize its rewards: wrap it with "
        "VecNormalize(env, norm_reward=True) (RL Zoo: `normalize: true`), or set iqr_thresholds for "
        "your return scale and silence this UnnormalizedRewardWarning",
        UnnormalizedRewardWarning,
        stacklevel=5,
    )
