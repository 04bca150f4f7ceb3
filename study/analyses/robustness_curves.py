"""A long run's robustness curve from its kept checkpoints, and what it says: status, trend, shipping check.

``update_curve`` evaluates the checkpoints of a run (``<run>/checkpoints/rl_model_<steps>_steps.zip`` and
its normalizer, written by the trainer) at least ``every`` steps after the previous row of the curve, and
the run's newest model, on the cases of ``sb3_huri.runner.robustness`` (the six Table-1 scenarios,
``side-impact``, ``nominal@1.0`` and ``nominal@0.5``), and adds a row per checkpoint to the run's
``robustness.csv``. A row evaluated with another number of episodes is evaluated again where its
checkpoint is still there, and kept as it is otherwise, so that a curve started on few robots can be
redone on more without losing the points whose checkpoints are gone.

``write_summary`` writes the run's status (sessions, training figures per 1M steps from ``curve.csv``) and
the curve as markdown into the run folder (``robustness.md``): the run's own record, regenerated from its
files. The campaign's results page (``study.results``) draws every run's curve
beside the others. ``study.scripts.robustness_curve`` is the command line.
"""

from __future__ import annotations

import csv
import re
import tempfile
import time
from pathlib import Path

import numpy as np

from sb3_huri.experiments.statistics import wilson_interval
from sb3_huri.runner.evaluation import TABLE1_SCENARIOS
from sb3_huri.runner.files import write_text
from sb3_huri.runner.folder import load_run
from sb3_huri.runner.robustness import CASES, NOMINAL, add_row, read_rows, robustness_row
from sb3_huri.runner.state import RunState
from zerith_gym import ZERITH1_ID

SUMMARY_FILE = "robustness.md"
"""The run's status and robustness curve in markdown, written into the run folder by ``write_summary``."""


def checkpoints(run: Path) -> dict[int, tuple[Path, Path]]:
    """Model and normalizer of each saved checkpoint, by step; the run's newest model included."""
    found = {}
    for model in (run / "checkpoints").glob("rl_model_*_steps.zip"):
        steps = int(re.findall(r"_(\d+)_steps", model.name)[0])
        found[steps] = (model, run / "checkpoints" / f"rl_model_vecnormalize_{steps}_steps.pkl")
    newest = RunState.read(run).timesteps
    if newest and (run / f"{ZERITH1_ID}.zip").is_file():
        found[newest] = (run / f"{ZERITH1_ID}.zip", run / ZERITH1_ID / "vecnormalize.pkl")
    return dict(sorted(found.items()))


def evaluate_checkpoint(
    model_file: Path, normalizer_file: Path, episodes: int, seed: int
) -> dict[str, float]:
    """Survival per case, the Table-1 mean and the mean forward velocity at 1 m/s of one checkpoint."""
    with tempfile.TemporaryDirectory() as folder:  # RL Zoo's layout, which load_run reads
        layout = Path(folder)
        (layout / ZERITH1_ID).mkdir()
        (layout / f"{ZERITH1_ID}.zip").symlink_to(model_file.resolve())
        (layout / ZERITH1_ID / "vecnormalize.pkl").symlink_to(normalizer_file.resolve())
        model, normalizer = load_run(layout, ZERITH1_ID)
    return robustness_row(model, normalizer, episodes, seed)


def update_curve(run: Path, every: int, episodes: int, seed: int) -> list[int]:
    """Evaluate the checkpoints of ``run`` the curve lacks (``every`` steps apart at least, and the newest
    model) or holds with another number of ``episodes``, adding each row to ``robustness.csv`` as soon as it
    is evaluated (an interrupted update keeps what it did); returns the steps evaluated."""
    rows = read_rows(run)
    found = checkpoints(run)
    newest = max(found, default=None)
    evaluated = []
    for steps, (model_file, normalizer_file) in found.items():
        row = rows.get(steps)
        if row is not None and int(row["episodes"]) == episodes:
            continue
        previous = max((s for s in rows if s < steps), default=-every)  # kept rows count too
        if row is None and steps - previous < every and steps != newest:
            continue  # a row of another episode count is redone wherever its checkpoint is still there
        began = time.time()
        metrics = evaluate_checkpoint(model_file, normalizer_file, episodes, seed)
        metrics = {**metrics, "eval_s": round(time.time() - began)}
        rows[steps] = add_row(run, steps, metrics, episodes)
        evaluated.append(steps)
        print(rows[steps], flush=True)
        print("unmet shipping criteria:", unmet_ship_criteria(rows[steps]) or "none", flush=True)
    return evaluated


STATUS_COLUMNS = (
    "ep_len", "ep_return", "fall_rate", "scale", "approx_kl", "clip_fraction", "explained_variance", "std",
    "learning_rate",
)  # fmt: skip


def _summary(rows: list[dict[str, str]], key: str) -> float:
    """The median of a column over rows, or for `fall_rate` the mean: a rollout ends only a few episodes,
    so its fall rate is mostly 0 or 1 and the median hides how many fell."""
    values = sorted(float(r[key]) for r in rows if r[key] not in ("", "nan"))
    if not values:
        return float("nan")
    return sum(values) / len(values) if key == "fall_rate" else values[len(values) // 2]


def status_markdown(run: Path) -> str:
    """The run's sessions, and its training figures per 1M-step block and over the whole run."""
    state = RunState.read(run)
    with (run / "curve.csv").open() as file:
        rows = list(csv.DictReader(file))
    lines = [
        f"{state.timesteps:,} steps in {state.wall_s / 3600:.2f} h of training over {len(state.sessions)} "
        f"session(s); curriculum stage {state.curriculum_stage} (scale {rows[-1]['scale']}).",
        "",
        "| session started | steps | wall (min) | hardware |",
        "|---|---|---|---|",
    ]
    for session in state.sessions:
        steps = f"{session['from_timesteps']:,} -> {session.get('to_timesteps', session['from_timesteps']):,}"
        wall = session.get("wall_s", 0.0) / 60
        lines.append(f"| {session['started']} | {steps} | {wall:.0f} | {session['hardware']} |")
    lines += [
        "",
        "Per 1M steps, medians over the updates (`curve.csv`): mean training episode length and",
        "return, share of ended episodes that fell (the mean over rollouts, not the median), curriculum",
        "scale, approximate KL, clip fraction, critic explained variance, action noise, the actor's mean",
        "learning rate:",
        "",
        "| steps | wall (h) | ep len | return | falls | scale | approx_kl | clip | expl. var. | std | lr |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    blocks: dict[int, list[dict[str, str]]] = {}
    for row in rows:
        blocks.setdefault(int(row["timesteps"]) // 1_000_000, []).append(row)
    for block, members in [*blocks.items(), (-1, rows)]:
        label = "whole run" if block < 0 else f"{block}-{block + 1}M"
        wall = float(members[-1]["wall_s"]) / 3600
        cells = [_summary(members, key) for key in STATUS_COLUMNS]
        formatted = [f"{cells[0]:.0f}", f"{cells[1]:.0f}", *(f"{v:.3g}" for v in cells[2:])]
        lines.append(f"| {label} | {wall:.2f} | " + " | ".join(formatted) + " |")
    return "\n".join(lines)


TREND_CASES = ("table1_mean", "continuous-feet", "sudden-feet", "vx_at_1.0")
"""The columns whose trend since full scale the summary states: the Table-1 mean, the feet cases (the last
to rise) and the forward velocity at a 1 m/s command (m/s; a shipped agent must reach 0.8)."""


def trend(steps: np.ndarray, values: np.ndarray) -> tuple[float, float]:
    """Least-squares slope of `values` per 10M `steps` and the half-width of its 95% t interval.

    Whether a curve still rises is read from the slope over its points, not from two noisy ends."""
    from scipy import stats

    if len(steps) < 3:
        raise ValueError(f"a trend needs at least 3 points, got {len(steps)}")
    fit = stats.linregress(np.asarray(steps, dtype=float) / 1e7, np.asarray(values, dtype=float))
    return float(fit.slope), float(fit.stderr * stats.t.ppf(0.975, len(steps) - 2))


def full_scale_step(run: Path) -> int | None:
    """The first step at which the run's curriculum scale reached 1 (`curve.csv`), or None."""
    with (run / "curve.csv").open() as file:
        for row in csv.DictReader(file):
            if row.get("scale") not in (None, "", "nan") and float(row["scale"]) >= 1.0:
                return int(row["timesteps"])
    return None


RECENT_STEPS = 50_000_000
"""The window of the second trend the summary states: has the curve flattened lately?"""


def _slopes(rows: list[dict[str, str]]) -> str:
    """Each trend case's slope per 10M steps with its 95% half-width, over `rows`, as one sentence part."""
    steps = np.array([int(r["timesteps"]) for r in rows])
    parts = []
    for key in TREND_CASES:
        slope, half = trend(steps, np.array([float(r[key]) for r in rows]))
        parts.append(f"{key} {slope:+.3f} +- {half:.3f}")
    return ", ".join(parts)


def trend_markdown(run: Path, rows: list[dict[str, str]]) -> str:
    """How fast the curve rose since the curriculum reached full scale and over the last `RECENT_STEPS`
    (when that window starts later and holds 3 rows), or "" if too early."""
    since = full_scale_step(run)
    later = [r for r in rows if since is not None and int(r["timesteps"]) >= since]
    if len(later) < 3:
        return ""
    text = (
        f"Since the curriculum reached full scale ({since:,} steps), per 10M steps (least-squares slope over "
        f"{len(later)} rows, 95% t interval): {_slopes(later)}."
    )
    start = int(later[-1]["timesteps"]) - RECENT_STEPS
    recent = [r for r in later if int(r["timesteps"]) >= start]
    if start > int(later[0]["timesteps"]) and len(recent) >= 3:
        text += f" Over the last {RECENT_STEPS / 1e6:.0f}M steps ({len(recent)} rows): {_slopes(recent)}."
    return text


SHIP_MEAN = 0.8
SHIP_CASE_FLOOR = 0.6
SHIP_VX = 0.8
"""Shipping criteria of a robust agent: the Table-1 mean, the least any Table-1 case may survive and the
forward velocity at a 1 m/s command (m/s); `nominal@1.0` and `nominal@0.5` must also pass without a fall."""


def unmet_ship_criteria(row: dict[str, str]) -> list[str]:
    """The shipping criteria a row of the curve misses, each said with its number ([] when it ships)."""
    unmet = []
    if float(row["table1_mean"]) < SHIP_MEAN:
        unmet.append(f"Table-1 mean {float(row['table1_mean']):.3f} < {SHIP_MEAN}")
    unmet += [
        f"{case} {float(row[case]):.2f} < {SHIP_CASE_FLOOR}"
        for case in TABLE1_SCENARIOS
        if float(row[case]) < SHIP_CASE_FLOOR
    ]
    if float(row["vx_at_1.0"]) < SHIP_VX:
        unmet.append(f"vx at 1 m/s {float(row['vx_at_1.0']):.2f} < {SHIP_VX}")
    unmet += [f"{case} falls ({float(row[case]):.2f} survive)" for case in NOMINAL if float(row[case]) < 1.0]
    return unmet


def ship_markdown(rows: list[dict[str, str]]) -> str:
    """Which rows meet the shipping criteria, or what the newest row misses."""
    ready = [f"{int(r['timesteps']):,}" for r in rows if not unmet_ship_criteria(r)]
    if ready:
        return f"Rows that meet the shipping criteria: {', '.join(ready)} steps."
    return (
        "No row meets the shipping criteria yet; the newest misses: "
        + "; ".join(unmet_ship_criteria(rows[-1]))
        + "."
    )


def curve_markdown(run: Path) -> str:
    """The robustness curve as a table, with the 95% interval of the newest Table-1 mean."""
    rows = list(read_rows(run).values())
    if not rows:
        return "(no checkpoint evaluated yet)"
    header = ["steps", "wall (h)", "episodes", *CASES, "Table-1 mean", "vx @ 1.0"]
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    for row in rows:
        steps, wall = f"{int(row['timesteps']):,}", f"{float(row['wall_s']) / 3600:.2f}"
        cells = [steps, wall, row["episodes"], *(row[c] for c in CASES), row["table1_mean"], row["vx_at_1.0"]]
        lines.append("| " + " | ".join(cells) + " |")
    episodes = int(rows[-1]["episodes"])
    n = episodes * len(TABLE1_SCENARIOS)
    low, high = wilson_interval(float(rows[-1]["table1_mean"]), n)
    one_low, one_high = wilson_interval(0.5, episodes)
    lines += [
        "",
        f"{episodes} episodes per case in the newest row: its Table-1 mean ({n} episodes) lies in "
        f"[{low:.2f}, {high:.2f}] (95% Wilson interval); one case's share is known to about "
        f"+-{(one_high - one_low) / 2:.2f}.",
        "",
        ship_markdown(rows),
    ]
    sentence = trend_markdown(run, rows)
    return "\n".join([*lines, "", sentence] if sentence else lines)


def write_summary(run: Path) -> Path:
    """Write the run's status and robustness curve to ``<run>/robustness.md``, regenerated whole from the
    run's files; returns its path."""
    path = run / SUMMARY_FILE
    body = f"# {run.name}: status and robustness curve\n\n{status_markdown(run)}\n\n"
    write_text(path, f"{body}Robustness curve:\n\n{curve_markdown(run)}\n")
    return path
