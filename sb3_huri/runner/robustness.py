"""A run's robustness learning curve, ``robustness.csv``: its checkpoints on the paper's Table-1 scenarios.

A row evaluates one checkpoint's deterministic policy on the six Table-1 scenarios (continuous and
sudden forces on centroid, hands and feet, at the test ranges and 1 m/s), on ``side-impact`` (one 200 N
push from the side), ``nominal@1.0`` and ``nominal@0.5``, each on the same ``episodes`` robots (seeds
``seed + i``) for every checkpoint, and records the steps, the run's training wall time at that step
(``curve.csv``), the hardware it trained on (``state.json``), the episodes per case, each case's survival,
the Table-1 mean and the mean forward velocity at 1 m/s. The trainer writes a row every few million steps
while it trains (``sb3_huri.runner.training.RobustnessSchedule``);
``study.analyses.robustness_curves`` (``study.scripts.robustness_curve``) evaluates kept
checkpoints afterwards.
"""

from __future__ import annotations

import csv
import time
from pathlib import Path
from typing import Any

from sb3_huri.runner.curve import wall_time_at
from sb3_huri.runner.evaluation import TABLE1_SCENARIOS, evaluate, parse_case, random_states_kept
from sb3_huri.runner.files import replaced
from sb3_huri.runner.state import RunState

ROBUSTNESS_FILE = "robustness.csv"
NOMINAL = ("nominal@1.0", "nominal@0.5")
CASES = (*TABLE1_SCENARIOS, "side-impact", *NOMINAL)
COLUMNS = ("timesteps", "wall_s", "hardware", "episodes", *CASES, "table1_mean", "vx_at_1.0", "eval_s")
EARLY_EPISODES = 10
"""Episodes per case of the rows written before the file had an `episodes` column."""


def robustness_row(
    model: Any,
    normalizer: Any | None,
    episodes: int,
    seed: int,
    workers: int | None = None,
    episode_steps: int | None = None,
) -> dict[str, float]:
    """Survival per case, the Table-1 mean and the mean forward velocity at 1 m/s, of `model`'s
    deterministic policy (observations normalized by `normalizer`, a `VecNormalize`, or None), in episodes
    of `episode_steps` (default: the env's 20 s).

    The global random states of torch, numpy and Python are left as they were, so that a training that
    evaluates itself between rollouts learns what it would have learnt without the evaluation."""
    row: dict[str, float] = {}
    began = time.time()
    with random_states_kept():
        for case in CASES:
            scenario, command = parse_case(case)
            metrics = evaluate(
                model,
                normalizer,
                scenario,
                command,
                episodes,
                seed,
                workers=workers,
                episode_steps=episode_steps,
            )
            row[case] = round(metrics["survive"], 3)
            if case == "nominal@1.0":
                row["vx_at_1.0"] = round(metrics["vx"], 3)
    row["table1_mean"] = round(sum(row[c] for c in TABLE1_SCENARIOS) / len(TABLE1_SCENARIOS), 3)
    row["eval_s"] = round(time.time() - began)
    return row


def read_rows(run: Path) -> dict[int, dict[str, str]]:
    """The evaluated rows of a run's `robustness.csv` by step, each with its `episodes` per case."""
    path = run / ROBUSTNESS_FILE
    if not path.is_file():
        return {}
    with path.open() as file:
        rows = {int(row["timesteps"]): row for row in csv.DictReader(file)}
    for row in rows.values():
        row["episodes"] = row.get("episodes") or str(EARLY_EPISODES)
    return dict(sorted(rows.items()))


def write_rows(run: Path, rows: dict[int, dict[str, Any]]) -> None:
    """Write every row, by step, through a temporary file: an interrupted write leaves the old file."""
    with replaced(run / ROBUSTNESS_FILE) as temporary, temporary.open("w", newline="") as file:
        writer = csv.DictWriter(file, fieldnames=COLUMNS)
        writer.writeheader()
        writer.writerows(row for _, row in sorted(rows.items()))


def add_row(run: Path, steps: int, metrics: dict[str, float], episodes: int) -> dict[str, Any]:
    """Add (or replace) the row of `steps` with `metrics` (`robustness_row`'s) and the run's wall time and
    hardware at that step; returns the row."""
    rows = read_rows(run)
    rows[steps] = {
        "timesteps": steps,
        "wall_s": wall_time_at(run, steps),
        "hardware": RunState.read(run).hardware_at(steps),
        "episodes": episodes,
        **metrics,
    }
    write_rows(run, rows)
    return rows[steps]
