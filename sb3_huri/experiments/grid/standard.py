"""A run of the grid on a standard Gymnasium task (``HalfCheetah-v5``, ``Walker2d-v5``, any registered env
that is not a Zerith robot): trained as ``rl_zoo3 train --algo <method> --env <env> -conf <file>`` trains it,
resumable, and its final model evaluated on the task's own return.

Training builds what RL Zoo builds from the preset: ``make_vec_env`` of ``n_envs`` copies seeded
``seed + i`` (each in SB3's ``Monitor``), ``VecNormalize`` as RL Zoo reads ``normalize`` (its ``gamma``
the preset's), ``HuRiPPO(method=method, seed=seed)`` with the preset's hyperparameters and its
``callback:`` entries. The runner's checkpoint (``sb3_huri.runner.checkpoint.RunCheckpoint``) writes the
run folder in RL Zoo's layout between rollouts: ``<env>.zip``, ``<env>/vecnormalize.pkl``, ``config.yml``,
``args.yml``, ``state.json`` (steps, wall time, each session's hardware) and ``curve.csv``; a later
command trains on from it with the model, normalizer and random states restored and the envs reseeded
``seed + steps``, as the runner resumes every run. The folder is held (``sb3_huri.runner.lock``) for the
whole training, and a damaged newest checkpoint falls back to the previous one (``sb3_huri.runner.fallback``).

Evaluation: the newest checkpoint's deterministic policy on ``settings.eval.episodes`` episodes of one env
seeded ``settings.eval.seed`` (the same episodes' starts for every run), under the env's own time limit,
observations normalized with the training statistics frozen, and the episode returns unnormalized (the
task's true return, from the ``Monitor`` inside the normalizer: SB3's ``evaluate_policy``). The record is
``<run>/evaluations/<steps>.json``, in the runner's record format with one case, ``RETURN_CASE``.
"""

from __future__ import annotations

import time
from dataclasses import asdict
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from sb3_huri.experiments.grid.layout import RunStatus, Settings, write_status
from sb3_huri.runner.build import preset_normalized
from sb3_huri.runner.files import RunError, read_json, write_json
from sb3_huri.runner.record import record_path
from sb3_huri.runner.state import RunState, hardware

RETURN_CASE = "return"
"""The one case of a standard task's evaluation record: the episodes' true returns and lengths."""


def make_env(env_id: str, preset: dict[str, Any], seed: int, n_envs: int | None = None) -> Any:
    """The preset's vectorized env as RL Zoo makes it (``make_vec_env``, each copy in a ``Monitor``, copy i
    seeded ``seed + i``), without its normalizer."""
    from stable_baselines3.common.env_util import make_vec_env

    count = int(n_envs or preset["n_envs"])
    return make_vec_env(env_id, n_envs=count, seed=seed, env_kwargs=dict(preset.get("env_kwargs") or {}))


def _model(folder: Path, settings: Settings, method: str, seed: int, env: Any) -> Any:
    """A new model of the preset, or the run's newest checkpoint on `env`, ready to go on from a reset."""
    from sb3_huri import HuRiPPO
    from sb3_huri.runner.build import preset_model, resume_overrides
    from sb3_huri.runner.state import restore_random_states

    model_file = folder / f"{settings.env}.zip"
    if not model_file.is_file():
        return preset_model(settings.preset, env, method=method, seed=seed, device="cpu", verbose=0)
    saved_args = yaml.safe_load((folder / settings.env / "args.yml").read_text())
    if (saved_args.get("algo"), saved_args.get("seed")) != (method, seed):
        raise RunError(f"{folder} is a run of {saved_args.get('algo')} seed {saved_args.get('seed')}")
    saved = yaml.safe_load((folder / settings.env / "config.yml").read_text())
    model = HuRiPPO.load(model_file, env, device="cpu", **resume_overrides(saved, settings.preset))
    restore_random_states(folder, settings.env)
    env.seed(seed + model.num_timesteps)  # reproducible from this checkpoint, from a reset
    model._last_obs = None
    return model


def train_standard_run(folder: Path, status: RunStatus, settings: Settings) -> RunStatus:
    """Train the run in ``folder`` to ``settings.timesteps`` steps (whole rollouts), from its newest
    checkpoint if it has one, and return its status. A Ctrl-C raises KeyboardInterrupt in the training; the
    run resumes from its newest checkpoint."""
    from rl_zoo3.utils import get_callback_list
    from stable_baselines3.common.callbacks import CallbackList

    from sb3_huri.runner.checkpoint import RunCheckpoint
    from sb3_huri.runner.fallback import recover
    from sb3_huri.runner.lock import hold_run

    with hold_run(folder):
        recover(folder, settings.env, echo=lambda line: print(line, flush=True))
        resumed = RunState.read(folder, settings.env).timesteps
        if resumed:
            status.resumed_from.append(resumed)
        status.state, status.trained_to, status.evaluated = "training", None, None
        status.checkpoint, status.steps = resumed or None, resumed
        write_status(folder, status)
        saved = folder / settings.env / "vecnormalize.pkl"
        env = make_env(settings.env, settings.preset, seed=status.seed)
        env = preset_normalized(env, settings.preset, saved if resumed and saved.is_file() else None)
        try:
            model = _model(folder, settings, status.method, status.seed, env)
            run_args = {"algo": status.method, "env": settings.env, "seed": status.seed}
            run_args["env_kwargs"] = dict(settings.preset.get("env_kwargs") or {})
            checkpoint = RunCheckpoint(
                folder, settings.preset, run_args, settings.checkpoint_freq, env_id=settings.env
            )
            budget = settings.timesteps - model.num_timesteps
            if budget > 0:
                callbacks = CallbackList([*get_callback_list(settings.preset), checkpoint])
                model.learn(budget, callback=callbacks, reset_num_timesteps=model.num_timesteps == 0)
            steps = checkpoint.saved_steps if budget > 0 else model.num_timesteps
        finally:
            env.close()
    status.checkpoint, status.steps = steps, steps
    status.train_seconds, status.trained_to = RunState.read(folder, settings.env).wall_s, settings.timesteps
    write_status(folder, status)
    return status


def evaluate_standard_run(folder: Path, status: RunStatus, settings: Settings) -> RunStatus:
    """Evaluate the newest checkpoint of the run in ``folder`` into its record (see the module docstring);
    a record of other settings is replaced. Returns the final status."""
    steps = RunState.read(folder, settings.env).timesteps
    status.state, status.eval_cases, status.eval_done = "evaluating", 1, 0
    write_status(folder, status)
    path = record_path(folder, steps)
    about = {"method": status.method, "seed": status.seed}
    header = {**about, "steps": steps, "settings": asdict(settings.eval)}
    record = read_json(path, "an evaluation record") if path.is_file() else None
    if not (isinstance(record, dict) and all(record.get(k) == v for k, v in header.items())):
        record = evaluate_checkpoint(folder, settings.env, settings.eval.episodes, settings.eval.seed)
        record = {**header, **record}
        write_json(path, record)
    status.checkpoint, status.eval_done, status.eval_seconds = steps, 1, float(record["eval_s"])
    status.evaluated = {**asdict(settings.eval), "trained_to": status.trained_to}
    status.state = "done"
    write_status(folder, status)
    return status


def evaluate_checkpoint(folder: Path, env_id: str, episodes: int, seed: int) -> dict[str, Any]:
    """The run's newest checkpoint on `episodes` deterministic episodes of one env seeded `seed`: the record's
    body (model file, the run's training wall time and hardware, the evaluation's time and machine, and
    ``cases[RETURN_CASE]``: mean and standard deviation of the returns, each episode's return and length)."""
    import gymnasium as gym
    from stable_baselines3.common.evaluation import evaluate_policy

    from sb3_huri.runner.evaluation import random_states_kept
    from sb3_huri.runner.folder import load_model

    began = time.time()
    state = RunState.read(folder, env_id)
    preset = yaml.safe_load((folder / env_id / "config.yml").read_text())
    saved = folder / env_id / "vecnormalize.pkl"
    with random_states_kept():
        model = load_model(folder / f"{env_id}.zip")
        env = preset_normalized(
            make_env(env_id, preset, seed=seed, n_envs=1), preset, saved if saved.is_file() else None
        )
        try:
            if hasattr(env, "training"):
                env.training, env.norm_reward = False, False  # frozen statistics, the task's own rewards
            returns, lengths = evaluate_policy(
                model, env, n_eval_episodes=episodes, deterministic=True, return_episode_rewards=True
            )
        finally:
            env.close()
    returns = [float(r) for r in returns]
    case = {
        "mean_return": float(np.mean(returns)),
        "std_return": float(np.std(returns)),
        "returns": returns,
        "lengths": [int(n) for n in lengths],
        "time_limit": gym.spec(env_id).max_episode_steps,
    }
    return {
        "model": f"{env_id}.zip",
        "wall_s": state.wall_s,
        "hardware": state.hardware_until(state.timesteps),
        "eval_s": round(time.time() - began, 2),
        "eval_hardware": hardware(),
        "cases": {RETURN_CASE: case},
    }
