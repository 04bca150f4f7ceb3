"""Evaluating one run of the grid: its newest checkpoint on the paper's protocol, into the run's evaluation
record (``sb3_huri.runner.record``: ``<run>/evaluations/<steps>.json``), the format the campaign writes too.

The record is written case by case, so an interrupted evaluation continues with the next case; the run's
``status.json`` follows its progress. A record of other evaluation settings (the command changed them) is
moved out of the way and the checkpoint evaluated again.
"""

from __future__ import annotations

from dataclasses import asdict
from pathlib import Path

from sb3_huri.experiments.grid.layout import RunStatus, Settings, write_status
from sb3_huri.runner.evaluation import PROTOCOL
from sb3_huri.runner.folder import saved_models
from sb3_huri.runner.record import EVALUATIONS, evaluate_checkpoint, read_record, record_path


def evaluate_run(folder: Path, status: RunStatus, settings: Settings, workers: int = 0) -> RunStatus:
    """Evaluate the trained run in ``folder`` (its newest checkpoint) on every case of ``PROTOCOL``; return
    its final status."""
    models = saved_models(folder, settings.env)
    steps = max(models)
    previous = read_record(folder, steps)
    if previous is not None and previous.get("settings") != asdict(settings.eval):
        _discard(folder, steps)
    status.state, status.eval_cases, status.eval_done = "evaluating", len(PROTOCOL), 0
    write_status(folder, status)

    def progress(done: int, eval_s: float) -> None:
        status.eval_done, status.eval_seconds = done, eval_s  # the record's time, all attempts
        write_status(folder, status)

    about = {"method": status.method, "seed": status.seed}
    evaluate_checkpoint(
        folder, steps, models[steps], PROTOCOL, settings.eval, about,
        env_id=settings.env, workers=workers, progress=progress,
    )  # fmt: skip
    status.checkpoint, status.eval_done = steps, len(PROTOCOL)
    status.evaluated = {**asdict(settings.eval), "trained_to": status.trained_to}
    status.state = "done"
    write_status(folder, status)
    return status


def _discard(folder: Path, steps: int) -> None:
    """Remove the record of the checkpoint at `steps` and its risk traces."""
    record_path(folder, steps).unlink()
    for trace in (folder / EVALUATIONS).glob(f"{steps}-risk_*.npz"):
        trace.unlink()
