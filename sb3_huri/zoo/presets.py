"""RL Zoo presets: the hyperparameter files ``rl_zoo3 train -conf`` reads, and what each entry means.

A preset is one env's entry of an RL Zoo hyperparameter file (``hyperparams/*.yml``): the entries RL Zoo
reads itself (``ZOO_ONLY_KEYS``: robots, steps, policy, normalization, env options, callbacks) and the
algorithm's keyword arguments. ``sb3_huri.runner`` builds what ``rl_zoo3 train`` builds from the same preset.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

# The presets shipped inside the package (``sb3_huri/zoo/hyperparams`` links to the repository's
# ``hyperparams`` folder, as ``rl_zoo3/hyperparams`` does in RL Zoo).
PRESETS_FILE = Path(__file__).parent / "hyperparams" / "huri.yml"


ZOO_ONLY_KEYS = ("n_envs", "n_timesteps", "policy", "normalize", "env_kwargs", "callback", "frame_stack")
"""Preset entries RL Zoo reads itself; the others are the algorithm's keyword arguments."""


def read_preset(env_id: str, path: str | os.PathLike | None = None) -> dict[str, Any]:
    """The preset of `env_id` in an RL Zoo hyperparameter file (default: the packaged ``huri.yml``)."""
    import yaml

    path = Path(path or PRESETS_FILE)
    with open(path) as f:
        presets = yaml.safe_load(f)
    if env_id not in presets:
        raise ValueError(f"{path} has no preset for {env_id!r}; presets: {', '.join(presets)}")
    return dict(presets[env_id])


def algorithm_kwargs(preset: dict[str, Any]) -> dict[str, Any]:
    """The algorithm's keyword arguments of a preset, with ``policy_kwargs`` evaluated as RL Zoo does."""
    import torch as th

    kwargs = {k: v for k, v in preset.items() if k not in ZOO_ONLY_KEYS}
    if isinstance(kwargs.get("policy_kwargs"), str):
        kwargs["policy_kwargs"] = eval(kwargs["policy_kwargs"], {"nn": th.nn, "th": th})
    return kwargs


def normalize_kwargs(preset: dict[str, Any]) -> dict[str, Any] | None:
    """``VecNormalize`` keyword arguments of a preset's ``normalize`` entry (None: no normalization)."""
    value = preset.get("normalize", False)
    if isinstance(value, str):
        return eval(value)
    return {} if value else None
