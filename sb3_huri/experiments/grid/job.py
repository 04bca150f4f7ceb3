"""One run's work, as a backend executes it: train it to the requested steps, then evaluate it.

``execute_run`` is the unit both backends ship (a process-pool job or a Ray task). It takes everything
from the experiment folder, so it can run on any machine that sees that folder, and it can be started
again at any time: it trains on from the last checkpoint and evaluates only what is missing.
"""

from __future__ import annotations

import traceback
from dataclasses import asdict, dataclass
from pathlib import Path

from sb3_huri.experiments.grid.layout import (
    RunBusy,
    is_standard,
    load_settings,
    read_status,
    run_folder,
    run_lock,
    write_status,
)
from sb3_huri.runner.files import RunError


@dataclass(frozen=True)
class RunJob:
    """A run of the grid for a backend: the experiment folder, the run, and the cores it may use."""

    out: str
    """The experiment folder (absolute: Ray nodes must see it at the same path)."""
    method: str
    seed: int
    cpus: int = 1
    """Cores for this run: its robots are stepped by that many worker processes when it has enough
    robots for them (``training.env_workers``), else in the run's own process."""


@dataclass(frozen=True)
class RunOutcome:
    """What became of a run: ``done``, ``busy`` (locked by a live process) or ``failed``."""

    method: str
    seed: int
    state: str
    message: str = ""
    steps: int = 0
    train_seconds: float = 0.0
    eval_seconds: float = 0.0


def execute_run(task: RunJob) -> RunOutcome:
    """Train the run of ``task`` to the experiment's steps (resuming), then evaluate it if it is not yet: a
    Zerith env on its batched env and the paper's protocol, a standard task by ``grid.standard``.

    Never raises for a failing run: the error is kept in its ``status.json`` and returned, so one broken
    run does not stop the grid (Ctrl-C and kills stop it, and are resumed by the next command).
    """
    import torch as th

    from sb3_huri.experiments.grid.evaluation import evaluate_run
    from sb3_huri.experiments.grid.standard import evaluate_standard_run, train_standard_run
    from sb3_huri.experiments.grid.training import env_workers, train_grid_run

    th.set_num_threads(1)  # small networks: one thread is fastest, and the runs share the machine
    out = Path(task.out)
    settings = load_settings(out)
    folder = run_folder(out, settings.env, task.method, task.seed)
    try:
        with run_lock(folder):
            status = read_status(folder, task.method, task.seed, settings.env)
            status.error = None
            try:
                standard = is_standard(settings.env)
                if status.trained_to is None or status.trained_to < settings.timesteps:
                    if standard:
                        status = train_standard_run(folder, status, settings)
                    else:
                        workers = env_workers(task.cpus, int(settings.preset["n_envs"]))
                        status = train_grid_run(folder, status, settings, workers)
                if status.evaluated != {**asdict(settings.eval), "trained_to": status.trained_to}:
                    if standard:
                        status = evaluate_standard_run(folder, status, settings)
                    else:
                        workers = env_workers(task.cpus, settings.eval.episodes)
                        status = evaluate_run(folder, status, settings, workers)
            except Exception:
                status.state, status.error = "failed", traceback.format_exc()
                write_status(folder, status)
                return RunOutcome(task.method, task.seed, "failed", status.error, status.steps)
            status.state = "done"
            write_status(folder, status)
            return RunOutcome(
                task.method, task.seed, "done", "", status.steps, status.train_seconds, status.eval_seconds
            )
    except RunBusy as error:
        return RunOutcome(task.method, task.seed, "busy", str(error))
    except RunError as error:
        return RunOutcome(task.method, task.seed, "failed", str(error))


def is_finished(out: Path, method: str, seed: int) -> bool:
    """Whether the run is trained to the experiment's steps and evaluated with its settings."""
    settings = load_settings(out)
    folder = run_folder(out, settings.env, method, seed)
    status = read_status(folder, method, seed, settings.env)
    return (
        status.trained_to is not None
        and status.trained_to >= settings.timesteps
        and status.evaluated == {**asdict(settings.eval), "trained_to": status.trained_to}
    )
