"""The evaluation record of a run's checkpoint: one file format that the grid's report and the campaign's
results page both read.

``evaluate_checkpoint`` runs a list of cases (``sb3_huri.runner.evaluation``: ``scenario`` or
``scenario@vx``) on the checkpoint of a run saved at some step, ``settings.episodes`` robots per case (robot i
seeded ``settings.seed + i``, the same robots for every agent, so that two agents pair robot by robot), and
writes, in ``<run>/evaluations/``::

    <steps>.json                   what the record is of (``about``: e.g. method, seed, entry), the steps,
                                   the model file, the settings, the run's training wall time and hardware up
                                   to that step, and per case the metrics of ``evaluate`` with each robot's
                                   outcome (``survived``: 1/0, ``fall_step``: the control step of its fall
                                   or null)
    <steps>-risk_<case>.npz        the critic's trace along robot 0's episode in the risk cases (Fig. 5;
                                   ``@`` in a case's name written ``-``)

While it runs, the cases done so far are kept in ``<steps>.json.partial`` (written atomically after each
case), which a later call with the same header continues from; the ``.json`` appears, whole, when the last
case is done. So a kill loses at most the case it was running, and a reader of ``<steps>.json`` never
takes a half-done evaluation for a finished one. Other analyses of a checkpoint lie beside it as
``<steps>-<analysis>.json``.

The evaluation may run inside a training process: the global random states of Python, NumPy and torch
are the same after the call as before it (loading a model reseeds them with the model's training seed).
"""

from __future__ import annotations

import math
import os
import time
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np

from sb3_huri.runner.curve import wall_time_at
from sb3_huri.runner.evaluation import (
    RISK_CASES,
    evaluate,
    parse_case,
    random_states_kept,
    risk_file,
    write_trace,
)
from sb3_huri.runner.files import RunError, read_json, write_json
from sb3_huri.runner.state import RunState
from zerith_gym import ZERITH1_ID, robot_of
from zerith_gym.core.task import EPISODE_STEPS

EVALUATIONS = "evaluations"
"""The folder of a run's evaluation records."""
PARTIAL = ".partial"
"""Suffix of the record while cases are still to run."""


@dataclass(frozen=True)
class EvalSettings:
    """How a checkpoint is evaluated: robots (episodes) per case, their seed, and the time limit."""

    episodes: int = 10
    seed: int = 1000
    episode_steps: int = EPISODE_STEPS
    """Control steps of an episode (20 s, as the paper's tests)."""


def record_path(run: Path, steps: int) -> Path:
    """The record of the run's checkpoint at `steps` (``<run>/evaluations/<steps>.json``)."""
    return run / EVALUATIONS / f"{steps}.json"


def trace_path(run: Path, steps: int, case: str) -> Path:
    """The risk trace of `case` in the record at `steps` (``<steps>-risk_nominal-1.npz``)."""
    return risk_file(run / EVALUATIONS, case, prefix=f"{steps}-")


def read_record(run: Path, steps: int) -> dict[str, Any] | None:
    """The finished record of the checkpoint at `steps`, or None if there is none."""
    path = record_path(run, steps)
    return read_json(path, "an evaluation record") if path.is_file() else None


def robot_outcomes(metrics: dict[str, Any]) -> dict[str, Any]:
    """``evaluate``'s per-robot metrics as JSON: ``survived`` (1/0 per robot) and ``fall_step`` (the control
    step of the fall, null where the robot did not fall) replace the NaN-coded array; ``domain`` goes."""
    record = {key: value for key, value in metrics.items() if key not in ("fall_step", "domain", "trace")}
    fall = np.asarray(metrics["fall_step"], dtype=float)
    record["survived"] = [int(math.isnan(step)) for step in fall]
    record["fall_step"] = [None if math.isnan(step) else int(step) for step in fall]
    return record


def evaluate_checkpoint(
    run: Path,
    steps: int,
    model_files: tuple[Path, Path | None],
    cases: Sequence[str],
    settings: EvalSettings,
    about: dict[str, Any],
    *,
    env_id: str = ZERITH1_ID,
    workers: int | None = 0,
    progress: Callable[[int, float], None] | None = None,
) -> Path:
    """Evaluate the run's checkpoint at `steps` (`model_files`: its model and normalizer files) on every
    case of `cases`; return the path of its record (see the module docstring), at once if it exists.

    `about`: what the record is of, written first in it (e.g. method and seed; the campaign's entry). A
    finished record of that step must be about the same, else RunError: two evaluations of one checkpoint
    need one of them moved away. `workers`: processes stepping the robots (0: all in this process, None: one
    per core). `progress(cases_done, eval_s)` is called after each case.
    """
    model_file, normalizer_file = model_files
    target = record_path(run, steps)
    if target.is_file():
        record = read_json(target, "an evaluation record")
        held = {key: record.get(key) for key in about}
        if held != about:
            raise RunError(
                f"{target} is an evaluation of {held}, not of {about}: move it away to evaluate the "
                "checkpoint again"
            )
        return target
    model = str(model_file.relative_to(run)) if model_file.is_relative_to(run) else str(model_file)
    header = {**about, "steps": steps, "model": model, "settings": asdict(settings)}
    state = RunState.read(run, env_id)
    record = {**header, "wall_s": wall_time_at(run, steps), "hardware": state.hardware_until(steps)}
    record.update(eval_s=0.0, cases={})
    partial = target.with_name(target.name + PARTIAL)
    if partial.is_file():
        previous = read_json(partial, "an evaluation under way")
        if all(previous.get(key) == value for key, value in header.items()):
            record.update(eval_s=previous.get("eval_s", 0.0), cases=previous.get("cases", {}))
    with random_states_kept():
        from sb3_huri.runner.folder import load_checkpoint

        loaded = load_checkpoint(model_file, normalizer_file)
        for case in cases:
            if case not in record["cases"]:
                began = time.time()
                record["cases"][case] = _evaluate_case(*loaded, run, steps, case, settings, env_id, workers)
                record["eval_s"] += time.time() - began
                write_json(partial, record)
            if progress is not None:
                progress(len(record["cases"]), record["eval_s"])
    os.replace(partial, target)
    return target


def _evaluate_case(
    model: Any,
    normalizer: Any | None,
    run: Path,
    steps: int,
    case: str,
    settings: EvalSettings,
    env_id: str,
    workers: int | None,
) -> dict[str, Any]:
    """One case's metrics with each robot's outcome; the risk trace written beside the record.

    Every method of this package, the scalar-critic PPO baseline included, has ``assess_risk`` (the
    baseline's single atom gives beta 0 and IQR 0): every agent is traced, as Fig. 5 asks."""
    scenario, command = parse_case(case)
    metrics = evaluate(
        model,
        normalizer,
        scenario,
        command,
        settings.episodes,
        settings.seed,
        episode_steps=settings.episode_steps,
        workers=workers,
        risk=case in RISK_CASES and hasattr(model, "assess_risk"),
        per_robot=True,
        robot=robot_of(env_id),
    )
    trace = metrics.get("trace")
    if trace is not None:
        write_trace(trace_path(run, steps, case), trace)
    return robot_outcomes(metrics)
