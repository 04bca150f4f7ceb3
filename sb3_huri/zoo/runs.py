"""Run folders in RL Zoo's layout: numbering new runs and saving a trained model where RL Zoo's tools look.

A run folder ``<log_folder>/<algo>/<env_id>_<id>`` holds ``<env_id>.zip`` and ``<env_id>/`` with
``config.yml`` (the preset), ``args.yml`` and, when observations were normalized, ``vecnormalize.pkl``.
``rl_zoo3 enjoy``, ``examples/watch_zerith.py`` and ``sb3_huri.zoo.load_run`` read it.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

DEFAULT_ENV_ID = "Zerith1-v0"


def next_run_folder(log_folder: str | os.PathLike, algo: str, env_id: str = DEFAULT_ENV_ID) -> Path:
    """``<log_folder>/<algo>/<env_id>_<id>`` with the next free id, as RL Zoo numbers its runs."""
    log_folder = Path(log_folder)
    ids = [
        int(p.name.rsplit("_", 1)[1])
        for p in (log_folder / algo).glob(f"{env_id}_*")
        if p.is_dir() and p.name.rsplit("_", 1)[1].isdigit()
    ]
    return log_folder / algo / f"{env_id}_{max(ids, default=0) + 1}"


def save_run(
    model: Any,
    run: str | os.PathLike,
    preset: dict[str, Any],
    args: dict[str, Any],
    env_id: str = DEFAULT_ENV_ID,
) -> None:
    """Model, normalizer, preset and arguments in RL Zoo's layout (what ``rl_zoo3 enjoy`` loads).

    The normalizer is saved when the model's env is a ``VecNormalize``. Model and normalizer are written to
    temporary files and renamed, so that a run stopped while saving keeps its previous files whole.
    """
    import yaml
    from stable_baselines3.common.vec_env import VecNormalize

    run = Path(run)
    stats = run / env_id
    stats.mkdir(parents=True, exist_ok=True)
    temporary = run / f".{env_id}.saving.zip"
    model.save(temporary)
    os.replace(temporary, run / f"{env_id}.zip")
    env = model.get_env()
    if isinstance(env, VecNormalize):
        env.save(str(stats / ".vecnormalize.saving.pkl"))
        os.replace(stats / ".vecnormalize.saving.pkl", stats / "vecnormalize.pkl")
    with open(stats / "config.yml", "w") as f:
        yaml.safe_dump(preset, f)
    with open(stats / "args.yml", "w") as f:
        yaml.safe_dump(args, f)
