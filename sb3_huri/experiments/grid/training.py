"""Training one run of the grid: the runner's trainer on the grid's run folder, and the run's status.

A run trains what ``examples/train_zerith.py``, the campaign and ``rl_zoo3 train --algo <method>`` train,
through the same trainer (``sb3_huri.runner.training.train_run``) and into the same run-folder format:
the env's preset on the batched env with ``VecNormalize`` and the preset's callbacks, checkpoints between
rollouts every ``checkpoint_freq`` steps (``<run>/Zerith1-v0.zip`` and ``<run>/Zerith1-v0/state.json``),
``curve.csv`` a row per rollout. The grid's ``status.json`` adds what its driver needs: the steps the run was
trained to, the checkpoints each resumption started from, and the evaluation's progress. A later command
with a larger ``--timesteps`` trains on from the newest checkpoint.
"""

from __future__ import annotations

from pathlib import Path

from sb3_huri.experiments.grid.layout import RunStatus, Settings, write_status


def env_workers(cpus: int, n_envs: int) -> int:
    """Worker processes stepping a run's robots when the run has ``cpus`` cores: the env's own choice for
    that many cores (``zerith_gym.cpu.workers.default_workers``: a slice of robots per core, the run's process
    stepping one of them; 0 with one core)."""
    from zerith_gym.cpu.workers import default_workers

    return default_workers(n_envs, cores=cpus)


def train_grid_run(folder: Path, status: RunStatus, settings: Settings, workers: int = 0) -> RunStatus:
    """Train the run in ``folder`` to ``settings.timesteps`` steps, from its newest checkpoint if it has one.

    ``workers``: processes stepping the robots (``zerith_gym.make_vec_env``). Returns the final status.
    A Ctrl-C raises KeyboardInterrupt in the training; the run resumes from its newest checkpoint.
    """
    import gymnasium as gym

    from sb3_huri.runner import RunRequest, TrainingOptions, train_run
    from sb3_huri.runner.state import RunState

    preset = dict(settings.preset)
    preset["env_kwargs"] = {**(gym.spec(settings.env).kwargs or {}), **(preset.get("env_kwargs") or {})}
    resumed = RunState.read(folder).timesteps
    if resumed:
        status.resumed_from.append(resumed)
    status.state, status.trained_to, status.evaluated = "training", None, None
    status.checkpoint, status.steps = resumed or None, resumed
    write_status(folder, status)
    request = RunRequest(folder, preset, status.method, status.seed, until=settings.timesteps)
    options = TrainingOptions(
        checkpoint_freq=settings.checkpoint_freq,
        device="cpu",
        workers=workers,
        verbose=0,
        stop_on_signals=False,  # a kill of the command ends its runs at once (backends.LocalBackend)
    )
    steps = train_run(request, options)
    state = RunState.read(folder)
    status.checkpoint, status.steps, status.train_seconds = steps, steps, state.wall_s
    status.trained_to = settings.timesteps
    write_status(folder, status)
    return status
