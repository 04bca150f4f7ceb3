"""What a run trains, built from its RL Zoo preset outside RL Zoo: the batched env with its normalizer, and
the model; for a resumed run, the hyperparameters its preset changes.

``train_run`` and the benchmarks build what ``rl_zoo3 train`` builds from the same preset, through these
functions.
"""

from __future__ import annotations

import os
from typing import Any

from sb3_huri.huri.methods import DEFAULT_METHOD
from sb3_huri.zoo import METHODS, algorithm_kwargs, normalize_kwargs


def preset_env(
    preset: dict[str, Any],
    *,
    seed: int,
    n_envs: int | None = None,
    normalizer: str | os.PathLike | None = None,
    **env_options: Any,
) -> Any:
    """The preset's batched Zerith env, wrapped in its `VecNormalize` if the preset normalizes.

    `n_envs` robots (default: the preset's), seeded `seed + i`, with the preset's `env_kwargs` updated by
    `env_options` (`scenario`, `workers`, `backend`, ...). `normalizer`: a saved `vecnormalize.pkl` to go on
    with (a resumed run); otherwise a new normalizer with the preset's settings and discount.
    """
    import zerith_gym

    env_kwargs = {**(preset.get("env_kwargs") or {}), **env_options}
    env = zerith_gym.make_vec_env(int(n_envs or preset["n_envs"]), seed=seed, **env_kwargs)
    return preset_normalized(env, preset, normalizer)


def preset_normalized(env: Any, preset: dict[str, Any], normalizer: Any = None) -> Any:
    """`env` in the preset's `VecNormalize` (RL Zoo's reading of `normalize`, the preset's discount), with
    the statistics of the saved `normalizer` file if given; `env` itself if the preset does not normalize."""
    from stable_baselines3.common.vec_env import VecNormalize

    norm = normalize_kwargs(preset)
    if norm is None:
        return env
    if normalizer is not None:
        return VecNormalize.load(str(normalizer), env)
    return VecNormalize(env, gamma=preset.get("gamma", 0.99), **norm)


def preset_model(
    preset: dict[str, Any], env: Any, *, method: str = DEFAULT_METHOD, seed: int = 0, **overrides: Any
) -> Any:
    """A new `HuRiPPO` of `method` (an RL Zoo algorithm name, `sb3_huri.zoo.METHODS`) with the preset's
    hyperparameters, any of them replaced by `overrides` (also `device`, `verbose`, `tensorboard_log`)."""
    from sb3_huri import HuRiPPO

    if method not in METHODS:
        raise ValueError(f"unknown method {method!r}; methods: {', '.join(METHODS)}")
    kwargs = {**algorithm_kwargs(preset), **overrides}
    return HuRiPPO(preset["policy"], env, method=method, seed=seed, **kwargs)


FIXED_BY_WEIGHTS = ("policy", "policy_kwargs", "n_quantiles")
"""Preset entries a checkpoint's network weights fix: a resumed run cannot change them."""


def resume_overrides(saved: dict[str, Any], preset: dict[str, Any]) -> dict[str, Any]:
    """The algorithm hyperparameters `preset` sets differently from the `saved` preset a run trained with:
    what its model is loaded with when it resumes under `preset` (as ``rl_zoo3 train -i`` continues a
    trained agent with its preset's). Entries `preset` leaves out keep their saved values. ValueError if
    a change touches the networks (`FIXED_BY_WEIGHTS`)."""
    old, new = algorithm_kwargs(saved), algorithm_kwargs(preset)

    def changes(key: str) -> bool:  # policy_kwargs compared as evaluated, not as written
        return saved.get(key) != preset[key] if key == "policy" else old.get(key) != new.get(key)

    fixed = [key for key in FIXED_BY_WEIGHTS if key in preset and changes(key)]
    if fixed:
        raise ValueError(
            f"a resumed run keeps its networks: {', '.join(fixed)} cannot change from the saved preset "
            f"({', '.join(f'{key}={saved.get(key)!r}' for key in fixed)}); start a new run instead"
        )
    return {key: value for key, value in new.items() if key not in old or old[key] != value}
