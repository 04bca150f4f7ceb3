"""Training one run of the grid, resumable from its last checkpoint.

A run trains what ``examples/train_zerith.py`` and ``rl_zoo3 train --algo <method>`` train: the env's
preset (``sb3_huri.zoo.read_preset``) on the batched env (``zerith_gym.make_vec_env``) with ``VecNormalize``
and the preset's callbacks (reward-term logs, randomization curriculum), ``HuRiPPO(variant=METHODS[method])``.
It adds, per run folder (``layout``):

- checkpoints of the model and its normalizer at the first rollout boundary after every
  ``checkpoint_freq`` steps (between rollouts, so that a checkpoint holds exactly the steps it trained
  on), each file written to a temporary name and renamed, then committed by naming it in
  ``status.json``; the two newest are kept;
- ``curve.csv``: after every rollout, the row every training of the package writes (``sb3_huri.zoo.curve``:
  steps, training seconds, SB3's mean return and length of the last 100 episodes, fall rate, curriculum
  scale and the update's figures);
- resuming: the model, normalizer and step count of the last committed checkpoint; the curriculum
  follows the model's step count, so it continues at its stage. The robots of a resumed run are seeded
  ``seed + steps`` (fresh draws rather than a replay of the first episodes), and the curve loses the
  rows after the checkpoint (they are trained again).

The final model is written in RL Zoo's layout (``sb3_huri.zoo.save_run``) and is also a checkpoint, so a
later command with a larger ``--timesteps`` trains on from it.
"""

from __future__ import annotations

from pathlib import Path

from sb3_huri.experiments.layout import RunStatus, Settings, write_status
from sb3_huri.experiments.run_files import checkpoint_paths


def env_workers(cpus: int, n_envs: int) -> int:
    """Worker processes stepping a run's robots when the run has ``cpus`` cores: the env's own choice for
    that many cores (``zerith_gym.workers.default_workers``: a slice of robots per core, the run's process
    stepping one of them; 0 with one core)."""
    from zerith_gym.workers import default_workers

    return default_workers(n_envs, cores=cpus)


def train_run(
    folder: Path,
    status: RunStatus,
    settings: Settings,
    workers: int = 0,
) -> RunStatus:
    """Train the run in ``folder`` to ``settings.timesteps`` steps, from its last checkpoint if it has one.

    ``workers``: processes stepping the robots (``zerith_gym.make_vec_env``). The status is written after
    every rollout (the steps, for the progress display). Returns the final status.
    """
    import gymnasium as gym
    import torch as th
    from rl_zoo3.utils import get_callback_list
    from stable_baselines3.common.callbacks import CallbackList

    from sb3_huri import HuRiPPO
    from sb3_huri.experiments.bookkeeping import RunBookkeeping
    from sb3_huri.zoo import save_run
    from sb3_huri.zoo.presets import preset_env, preset_model
    from zerith_gym.callbacks import RandomizationCurriculum

    th.set_num_threads(1)  # small networks: one thread is fastest, and several runs share the machine
    preset = dict(settings.preset)
    env_kwargs = {**(gym.spec(settings.env).kwargs or {}), **(preset.get("env_kwargs") or {})}
    resume = status.checkpoint
    seed = status.seed + (resume or 0)
    model_path, stats_path = checkpoint_paths(folder, resume or 0)
    normalizer = stats_path if resume is not None else None
    env = preset_env(preset, seed=seed, normalizer=normalizer, workers=workers, **env_kwargs)
    try:
        if resume is not None:
            model = HuRiPPO.load(model_path, env, device="cpu")
            model.set_random_seed(seed)
            model._last_obs = None  # start from a reset of the reseeded robots, not the saved observation
            status.resumed_from.append(resume)
        else:
            model = preset_model(preset, env, method=status.method, seed=status.seed, device="cpu", verbose=0)
        status.state, status.trained_to, status.evaluated = "training", None, None
        status.steps = model.num_timesteps
        write_status(folder, status)

        callbacks = get_callback_list(preset)
        curriculum = next((c for c in callbacks if isinstance(c, RandomizationCurriculum)), None)
        bookkeeping = RunBookkeeping(folder, status, settings.checkpoint_freq, curriculum)
        callbacks.append(bookkeeping)
        remaining = settings.timesteps - model.num_timesteps
        if remaining > 0:
            model.learn(remaining, callback=CallbackList(callbacks), reset_num_timesteps=resume is None)
        if status.checkpoint != model.num_timesteps:
            bookkeeping.checkpoint(model)
        save_run(
            model,
            folder,
            preset,
            {"algo": status.method, "env": settings.env, "seed": status.seed, "env_kwargs": env_kwargs},
            env_id=settings.env,
        )
        status.trained_to, status.steps = settings.timesteps, model.num_timesteps
        status.train_seconds = bookkeeping.wall_s
        write_status(folder, status)
        return status
    finally:
        env.close()
