"""The final evaluation of a campaign entry: its checkpoint at the entry's step, once, under the paper's
protocol.

An entry of the campaign's queue (``sb3_huri.experiments.campaign.queue``) trains a run folder up to
``entry.steps``; its evaluation takes the first model the run saved at or after that step
(``find_checkpoint``: the run's newest model or a kept checkpoint), runs every case of ``evaluation_cases``
(its robot's) on ``eval_episodes`` robots (robot i seeded ``eval_seed + i``, the same robots for every agent,
so two agents pair robot by robot) and writes, in ``<run>/evaluations/``::

    <steps>.json                   entry, protocol, method, seed, steps, the run's training wall time and
                                   hardware up to that step, the settings, and per case the metrics of
                                   ``evaluation.evaluate`` with each robot's outcome (``survived``: 1/0,
                                   ``fall_step``: the control step of its fall or null)
    <steps>-risk_<case>.npz        the critic's trace along robot 0's episode in the risk cases (Fig. 5)

While it runs, the cases done so far are kept in ``<steps>.json.partial`` (written atomically after each
case), which a later call continues from; the ``.json`` appears, whole, when the last case is done. So a
kill loses at most the case it was running, and ``CampaignEntry.evaluation`` (which reads ``*.json``) never
takes a half-done evaluation for a finished one.

The evaluation may run inside a training process: the global random states of Python, NumPy and torch
are the same after the call as before it (loading a model reseeds them with the model's training seed).
"""

from __future__ import annotations

import math
import os
import re
import time
from pathlib import Path
from typing import Any

import numpy as np

from sb3_huri.experiments.campaign.queue import ENV_ID, EVALUATIONS, CampaignEntry
from sb3_huri.experiments.evaluation import (
    PROTOCOL,
    RISK_CASES,
    evaluate,
    parse_case,
    random_states_kept,
    risk_file,
    write_trace,
)
from sb3_huri.experiments.layout import ExperimentError, atomic_write_json, read_json
from sb3_huri.experiments.robustness import wall_time_at
from zerith_gym.task import EPISODE_STEPS

EVALUATION_CASES = (*PROTOCOL, "side-impact", "nominal@0.5")
"""The paper's protocol (Table 1, Figs. 4 and 5, the terrain tests), one 200 N push from the side, and
walking at the training speed (0.5 m/s) on the plane: the robustness curve's two extra cases."""
QUADRUPED_CASES = ("nominal@1", "nominal@0.5", "platform-0.40", "platform-0.45")
"""The quadruped's: walking at 1 and 0.5 m/s on the plane, and the paper's Table 8 (stepping down a 0.40
and a 0.45 m platform at 1 m/s under a centroid force U[0, 100] N redrawn every 2 s, +-1 kg on the trunk)."""


def evaluation_cases(entry: CampaignEntry) -> tuple[str, ...]:
    """The cases of the entry's final evaluation: its robot's."""
    return QUADRUPED_CASES if entry.protocol == "quadruped" else EVALUATION_CASES


PARTIAL = ".partial"
"""Suffix of the evaluation file while cases are still to run."""
CHECKPOINTS = "checkpoints"
_CHECKPOINT = re.compile(r"rl_model_(\d+)_steps\.zip")


def saved_models(run: Path, env_id: str = ENV_ID) -> dict[int, tuple[Path, Path | None]]:
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


def find_checkpoint(entry: CampaignEntry) -> tuple[int, Path, Path | None]:
    """The entry's checkpoint: the first saved model at or after ``entry.steps`` (steps, model file,
    normalizer file). ExperimentError saying what the run holds when it has none that far."""
    found = saved_models(entry.run, entry.env_id)
    later = [steps for steps in found if steps >= entry.steps]
    if not later:
        held = ", ".join(f"{steps:,}" for steps in found) or "none"
        raise ExperimentError(
            f"entry {entry.name}: run {entry.run} has no saved model at or after {entry.steps:,} steps "
            f"(models held: {held}); train it further, or keep a checkpoint of that step in "
            f"{entry.run / CHECKPOINTS}"
        )
    steps = min(later)
    return steps, *found[steps]


def evaluation_path(run: Path, steps: int) -> Path:
    """The evaluation file of the run's checkpoint at ``steps`` (``<run>/evaluations/<steps>.json``)."""
    return run / EVALUATIONS / f"{steps}.json"


def trace_path(run: Path, steps: int, case: str) -> Path:
    """The risk trace of ``case`` in the evaluation at ``steps`` (``<steps>-risk_nominal-1.npz``)."""
    return risk_file(run / EVALUATIONS, case, prefix=f"{steps}-")


def hardware_until(run: Path, steps: int, env_id: str = ENV_ID) -> list[str]:
    """The machines that trained the run up to ``steps`` (its ``state.json`` sessions), each named once."""
    path = run / env_id / "state.json"
    sessions = read_json(path, "the run's training state").get("sessions", []) if path.is_file() else []
    names = [s.get("hardware", "unknown") for s in sessions if s.get("from_timesteps", 0) < steps]
    return list(dict.fromkeys(names))


def robot_outcomes(metrics: dict[str, Any]) -> dict[str, Any]:
    """``evaluate``'s per-robot metrics as JSON: ``survived`` (1/0 per robot) and ``fall_step`` (the control
    step of the fall, null where the robot did not fall) replace the NaN-coded array; ``domain`` goes."""
    record = {key: value for key, value in metrics.items() if key not in ("fall_step", "domain", "trace")}
    fall = np.asarray(metrics["fall_step"], dtype=float)
    record["survived"] = [int(math.isnan(step)) for step in fall]
    record["fall_step"] = [None if math.isnan(step) else int(step) for step in fall]
    return record


def _header(entry: CampaignEntry, steps: int, model: Path, episode_steps: int) -> dict[str, Any]:
    """What the evaluation is of, and how it is run: a partial file continues only if all of it matches."""
    return {
        "entry": entry.name,
        "protocol": entry.protocol,
        "method": entry.method,
        "seed": entry.seed,
        "steps": steps,
        "model": str(model.relative_to(entry.run)) if model.is_relative_to(entry.run) else str(model),
        "settings": {
            "episodes": entry.defaults.eval_episodes,
            "seed": entry.defaults.eval_seed,
            "episode_steps": episode_steps,
        },
    }


def _claimed(target: Path, entry: CampaignEntry) -> bool:
    """Whether ``target`` holds this entry's finished evaluation; ExperimentError if another entry's."""
    if not target.is_file():
        return False
    owner = read_json(target, "a final evaluation").get("entry")
    if owner != entry.name:
        raise ExperimentError(
            f"entry {entry.name}: its checkpoint {target.stem} was already evaluated for entry {owner} "
            f"({target}); two entries of one run need checkpoints at their own steps"
        )
    return True


def evaluate_entry(
    entry: CampaignEntry, workers: int | None = 0, *, episode_steps: int | None = None
) -> Path:
    """Evaluate the entry's checkpoint (``find_checkpoint``) on every case of ``evaluation_cases``; return
    the path of its evaluation file (see the module docstring), at once if it exists already.

    ``workers``: processes stepping the robots (``zerith_gym.make_vec_env``; 0: all in this process, None:
    one per core). ``episode_steps``: the time limit in control steps (default the env's 20 s).
    """
    steps, model_file, normalizer_file = find_checkpoint(entry)
    target = evaluation_path(entry.run, steps)
    if _claimed(target, entry):
        return target
    header = _header(entry, steps, model_file, episode_steps or EPISODE_STEPS)
    partial = target.with_name(target.name + PARTIAL)
    record = {
        **header,
        "wall_s": wall_time_at(entry.run, steps),
        "hardware": hardware_until(entry.run, steps, entry.env_id),
    }
    record.update(eval_s=0.0, cases={})
    if partial.is_file():
        previous = read_json(partial, "a final evaluation under way")
        if all(previous.get(key) == value for key, value in header.items()):
            record.update(eval_s=previous.get("eval_s", 0.0), cases=previous.get("cases", {}))
    with random_states_kept():
        from sb3_huri.zoo import load_checkpoint

        model, normalizer = load_checkpoint(model_file, normalizer_file)
        for case in evaluation_cases(entry):
            if case in record["cases"]:
                continue
            began = time.time()
            record["cases"][case] = _evaluate_case(model, normalizer, entry, steps, case, header, workers)
            record["eval_s"] += time.time() - began
            atomic_write_json(partial, record)
    os.replace(partial, target)
    return target


def _evaluate_case(
    model: Any,
    normalizer: Any | None,
    entry: CampaignEntry,
    steps: int,
    case: str,
    header: dict[str, Any],
    workers: int | None,
) -> dict[str, Any]:
    """One case's metrics with each robot's outcome; the risk trace written beside the evaluation file.

    Every method of this package, the scalar-critic PPO baseline included, has ``assess_risk`` (the
    baseline's single atom gives beta 0 and IQR 0): every final agent is traced, as Fig. 5 asks."""
    from sb3_huri.zoo import robot_of

    scenario, command = parse_case(case)
    settings = header["settings"]
    metrics = evaluate(
        model,
        normalizer,
        scenario,
        command,
        settings["episodes"],
        settings["seed"],
        episode_steps=settings["episode_steps"],
        workers=workers,
        risk=case in RISK_CASES and hasattr(model, "assess_risk"),
        per_robot=True,
        robot=robot_of(entry.env_id),
    )
    trace = metrics.get("trace")
    if trace is not None:
        path = trace_path(entry.run, steps, case)
        path.parent.mkdir(parents=True, exist_ok=True)
        write_trace(path, trace)
    return robot_outcomes(metrics)
