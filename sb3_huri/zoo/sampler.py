"""Optuna search space of HuRiPPO for ``rl_zoo3 train --algo <method> --optimize``.

Same structure as RL Zoo's own samplers: ``sample_huri_params`` suggests raw values (the names stored in
the Optuna study) and ``convert_huri_params`` turns them into HuRiPPO arguments, so that
``--storage ... --study-name ... --trial-id N`` can reload a trial. The networks are not searched: the sampled
values are merged over the preset, and replacing ``policy_kwargs`` would drop the preset's architecture.
"""

from __future__ import annotations

from typing import Any

import optuna


def sample_huri_params(
    trial: optuna.Trial, n_actions: int, n_envs: int, additional_args: dict[str, Any]
) -> dict[str, Any]:
    """Suggest PPO's and HuRi's hyperparameters for one trial (RL Zoo's sampler signature)."""
    params = {
        "n_steps_pow": trial.suggest_int("n_steps_pow", 5, 11),
        "n_minibatches": trial.suggest_categorical("n_minibatches", [1, 2, 4, 8]),
        "n_epochs": trial.suggest_categorical("n_epochs", [4, 5, 8, 10]),
        "learning_rate": trial.suggest_float("learning_rate", 1e-5, 2e-3, log=True),
        "one_minus_gamma": trial.suggest_float("one_minus_gamma", 1e-4, 0.03, log=True),
        "one_minus_gae_lambda": trial.suggest_float("one_minus_gae_lambda", 1e-3, 0.1, log=True),
        "ent_coef": trial.suggest_float("ent_coef", 1e-8, 0.02, log=True),
        "clip_range": trial.suggest_categorical("clip_range", [0.1, 0.2, 0.3]),
        "max_grad_norm": trial.suggest_float("max_grad_norm", 0.3, 2.0),
        "expectation_coef": trial.suggest_float("expectation_coef", 0.01, 1.0, log=True),
        "iqr_low": trial.suggest_float("iqr_low", 0.05, 0.5),
        "iqr_width": trial.suggest_float("iqr_width", 0.1, 1.0),
    }
    hyperparams = convert_huri_params(params)
    for name in ("n_steps", "gamma", "gae_lambda", "iqr_thresholds"):
        trial.set_user_attr(name, hyperparams[name])
    return hyperparams


def convert_huri_params(params: dict[str, Any]) -> dict[str, Any]:
    """Turn the raw values of a trial into HuRiPPO arguments."""
    hyperparams = dict(params)
    hyperparams["n_steps"] = 2 ** hyperparams.pop("n_steps_pow")
    hyperparams["gamma"] = 1.0 - hyperparams.pop("one_minus_gamma")
    hyperparams["gae_lambda"] = 1.0 - hyperparams.pop("one_minus_gae_lambda")
    low, width = hyperparams.pop("iqr_low"), hyperparams.pop("iqr_width")
    hyperparams["iqr_thresholds"] = (low, low + width)
    # The minibatch size follows the rollout size through ``n_minibatches``.
    hyperparams["batch_size"] = None
    return hyperparams
