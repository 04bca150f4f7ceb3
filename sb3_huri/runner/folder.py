"""Run folders in RL Zoo's layout: numbering new runs, saving a model where RL Zoo's tools look, loading it.

A run folder ``<log_folder>/<algo>/<env_id>_<id>`` holds ``<env_id>.zip`` and ``<env_id>/`` with
``config.yml`` (the preset), ``args.yml`` and, when observations were normalized, ``vecnormalize.pkl``;
kept copies of earlier checkpoints lie in ``checkpoints/`` (``rl_model_<steps>_steps.zip`` beside
``rl_model_vecnormalize_<steps>_steps.pkl``, as RL Zoo's ``CheckpointCallback`` names them).
``rl_zoo3 enjoy``, ``examples/watch_zerith.py`` and ``load_run`` read it.
"""

from __future__ import annotations

import difflib
import os
import pickle
import re
from pathlib import Path
from typing import Any

from sb3_huri.runner.files import read_json, replaced, write_text
from zerith_gym import ZERITH1_ID

CHECKPOINTS = "checkpoints"
"""The folder of a run's kept checkpoints."""
_CHECKPOINT = re.compile(r"rl_model_(\d+)_steps\.zip")


def next_run_folder(log_folder: str | os.PathLike, algo: str, env_id: str = ZERITH1_ID) -> Path:
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
    env_id: str = ZERITH1_ID,
) -> None:
    """Model, normalizer, preset and arguments in RL Zoo's layout (what ``rl_zoo3 enjoy`` loads).

    The normalizer is saved when the model's env is a ``VecNormalize``. Every file is written whole
    (``sb3_huri.runner.files``), so that a run stopped while saving keeps its previous files.
    """
    import yaml
    from stable_baselines3.common.vec_env import VecNormalize

    run = Path(run)
    stats = run / env_id
    stats.mkdir(parents=True, exist_ok=True)
    with replaced(run / f"{env_id}.zip") as temporary:
        model.save(temporary)
    env = model.get_env()
    if isinstance(env, VecNormalize):
        with replaced(stats / "vecnormalize.pkl") as temporary:
            env.save(str(temporary))
    write_text(stats / "config.yml", yaml.safe_dump(preset))
    write_text(stats / "args.yml", yaml.safe_dump(args))


def load_model(path: str | os.PathLike) -> Any:
    """A saved on-policy model on the CPU: ``HuRiPPO`` for every HuRi method, SB3's ``PPO`` otherwise.

    The saved policy class tells them apart: HuRi methods (the PPO baseline included) save a
    ``HuRiPolicy``, runs of SB3's own ``PPO`` an ``ActorCriticPolicy``.
    """
    from stable_baselines3 import PPO
    from stable_baselines3.common.save_util import load_from_zip_file

    from sb3_huri import HuRiPolicy, HuRiPPO

    data, _, _ = load_from_zip_file(path, device="cpu", load_data=True)
    policy_class = (data or {}).get("policy_class")
    algorithm = HuRiPPO if isinstance(policy_class, type) and issubclass(policy_class, HuRiPolicy) else PPO
    return algorithm.load(path, device="cpu")


def load_run(
    folder: str | os.PathLike, env_id: str, normalized: bool | None = None
) -> tuple[Any, Any | None]:
    """The model of a run folder in RL Zoo's layout (on the CPU) and its observation normalizer.

    The folder holds ``<env_id>.zip`` and, when the run normalized observations, ``<env_id>/vecnormalize.pkl``
    (as ``rl_zoo3 train`` and ``examples/train_zerith.py`` write them). The statistics are unpickled without
    building an environment (none is needed to normalize observations). `normalized`: None takes the
    statistics if there are any (None otherwise); True requires them (a model trained on normalized
    observations acts wrongly without them); False requires that there are none. Errors say what is missing.
    """
    import gymnasium as gym

    import zerith_gym  # noqa: F401  (registers the env ids)

    folder = Path(folder)
    if not folder.is_dir():
        raise FileNotFoundError(f"run folder {folder} not found")
    if env_id not in gym.registry:
        close = difflib.get_close_matches(env_id, list(gym.registry), n=3)
        hint = f"; did you mean {' or '.join(close)}?" if close else ""
        raise ValueError(f"unknown env id {env_id!r}: no Gymnasium environment is registered under it{hint}")
    model_path = folder / f"{env_id}.zip"
    if not model_path.is_file():
        raise FileNotFoundError(f"{model_path} not found: a run folder of {env_id} holds {env_id}.zip")
    stats = folder / env_id / "vecnormalize.pkl"
    if normalized and not stats.is_file():
        raise FileNotFoundError(
            f"{stats} not found: the run's VecNormalize statistics (observation mean and variance) are "
            "expected there, as rl_zoo3 train writes them; for a run trained without VecNormalize pass "
            "--unnormalized"
        )
    if normalized is False and stats.is_file():
        raise ValueError(f"--unnormalized given, but the run normalized its observations ({stats} exists)")
    return load_checkpoint(model_path, stats if stats.is_file() else None)


def load_checkpoint(
    model_file: str | os.PathLike, normalizer_file: str | os.PathLike | None
) -> tuple[Any, Any | None]:
    """A model file (on the CPU) and its observation normalizer file, wherever they lie: a run folder's
    newest model or one of its kept checkpoints (``checkpoints/rl_model_<steps>_steps.zip`` beside
    ``rl_model_vecnormalize_<steps>_steps.pkl``). ``normalizer_file`` None: a run without ``VecNormalize``.
    The statistics are unpickled without building an environment; ValueError if they are not VecNormalize's.
    """
    from stable_baselines3.common.vec_env import VecNormalize

    model = load_model(model_file)
    if normalizer_file is None:
        return model, None
    with open(normalizer_file, "rb") as file:
        normalizer = pickle.load(file)
    if not isinstance(normalizer, VecNormalize):
        kind = type(normalizer).__name__
        raise ValueError(f"{normalizer_file} holds a {kind}, not VecNormalize statistics")
    return model, normalizer


ROLLOUT_STATE = (
    "_last_obs",
    "_last_original_obs",
    "_last_episode_starts",
    "ep_info_buffer",
    "ep_success_buffer",
)
"""What a saved model holds of its robots' last step and episodes: needed to go on training in place, not to
act (a model loaded without it starts from its env's reset, as ``learn(reset_num_timesteps=True)`` does)."""


def copy_agent(run: str | os.PathLike, env_id: str, destination: str | os.PathLike) -> Path:
    """The agent of a run folder alone, in RL Zoo's layout at ``destination``, for sharing.

    The model keeps its networks and optimizer (so it can be trained on) and leaves out the rollout state
    (``ROLLOUT_STATE``); the normalizer keeps its statistics and leaves out its robots' last observations
    and rewards; ``config.yml`` and ``args.yml`` are copied. With 256 robots that is a few MB instead of the
    run's 6: what ``rl_zoo3 enjoy``, ``load_run`` and ``examples/watch_zerith.py`` read, and nothing else.
    """
    import shutil

    source, destination = Path(run), Path(destination)
    model, normalizer = load_run(source, env_id)
    (destination / env_id).mkdir(parents=True, exist_ok=True)
    model.save(destination / f"{env_id}.zip", exclude=list(ROLLOUT_STATE))
    if normalizer is not None:
        normalizer.old_obs, normalizer.old_reward = None, None
        # What VecNormalize.__getstate__ drops, absent from statistics unpickled without an env.
        normalizer.class_attributes, normalizer.returns = {}, None
        with open(destination / env_id / "vecnormalize.pkl", "wb") as file:
            pickle.dump(normalizer, file)
    for name in ("config.yml", "args.yml"):
        shutil.copyfile(source / env_id / name, destination / env_id / name)
    return destination


def saved_models(run: Path, env_id: str = ZERITH1_ID) -> dict[int, tuple[Path, Path | None]]:
    """Every complete model the run folder holds, by step: model file and normalizer file (None for a run
    without ``VecNormalize``). The run's newest model (step from ``state.json``) and its kept checkpoints;
    a checkpoint without its normalizer in a run that normalizes (a kill between the two files) is left out.
    `env_id`: the env the run trained on (its files' names).
    """
    newest_normalizer = run / env_id / "vecnormalize.pkl"
    folder = run / CHECKPOINTS
    kept = {
        int(match.group(1)): folder / match.group(0)
        for match in (_CHECKPOINT.fullmatch(p.name) for p in folder.glob("rl_model_*_steps.zip"))
        if match
    }
    normalizers = {steps: folder / f"rl_model_vecnormalize_{steps}_steps.pkl" for steps in kept}
    normalizes = newest_normalizer.is_file() or any(path.is_file() for path in normalizers.values())
    found: dict[int, tuple[Path, Path | None]] = {}
    for steps, model in kept.items():
        if normalizers[steps].is_file():
            found[steps] = (model, normalizers[steps])
        elif not normalizes:
            found[steps] = (model, None)
    state = run / env_id / "state.json"
    if (run / f"{env_id}.zip").is_file() and state.is_file():
        steps = int(read_json(state, "the run's training state")["timesteps"])
        found[steps] = (run / f"{env_id}.zip", newest_normalizer if newest_normalizer.is_file() else None)
    return dict(sorted(found.items()))
