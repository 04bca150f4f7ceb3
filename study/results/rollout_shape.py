"""The results page's check of a rollout shape: the robust recipe with 256 robots x 64 steps per update
against the same recipe with 32 robots x 512 steps, seed for seed, at the same samples (campaign protocol
``robust-256`` against ``robust``).

Both shapes collect 16,384 samples per update and update alike; the wider one steps more robots at once and
so trains more samples per second (docs/performance.md). It joins the comparison of methods only if it
learns per sample as the 32-robot recipe does: the same training return, fall rate and Table-1 survival at
the same steps, under the same curriculum (which grows with steps, so it is at the same scale for both).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from sb3_huri.experiments.markdown import table
from sb3_huri.experiments.statistics import mean_ci
from sb3_huri.runner.curve import read_curve
from sb3_huri.runner.robustness import read_rows
from study.campaign.queue import CampaignEntry
from study.results.evaluations import (
    FIGURE_DPI,
    Evaluated,
    comparable,
    method_label,
    runs_of,
    smoothed_curve,
)
from study.results.markdown import figure_lines, link, millions, save_figure
from study.results.sections import heading, section
from study.results.tables import pair_table

WIDE, REFERENCE = "robust-256", "robust"
"""The protocol of the shape under test, and the protocol it is held to."""
ROW_TOLERANCE = 0.2
"""How far a robustness row may lie from a checkpoint to stand for it, as a share of the spacing of the
checkpoints (1M steps at 5M): the older runs' rows were evaluated at other steps than every 5M."""


def matched_runs(entries: Sequence[CampaignEntry]) -> list[tuple[CampaignEntry, CampaignEntry]]:
    """Each ``robust-256`` run with the ``robust`` run of its method and seed (the first entry of each run),
    where the queue holds both."""
    first = [run_entries[0] for run_entries in runs_of(entries).values()]
    reference = {(e.method, e.seed): e for e in first if e.protocol == REFERENCE}
    return [
        (wide, reference[(wide.method, wide.seed)])
        for wide in first
        if wide.protocol == WIDE and (wide.method, wide.seed) in reference
    ]


def _value_at(curve: tuple[np.ndarray, np.ndarray], step: int) -> float:
    """The smoothed curve's value at ``step``, NaN beyond where the run has got to."""
    steps, values = curve
    if not steps.size or step > steps[-1]:
        return math.nan
    return float(np.interp(step, steps, values))


def _table1_at(run: Path, step: int, every: int) -> float:
    """The Table-1 mean of the run's robustness row nearest ``step`` (within ``ROW_TOLERANCE`` of the
    checkpoints' spacing ``every``), else NaN."""
    rows = read_rows(run)
    nearest = min(rows, key=lambda s: abs(s - step), default=None)
    if nearest is None or abs(nearest - step) > ROW_TOLERANCE * every:
        return math.nan
    return float(rows[nearest]["table1_mean"])


def samples_per_second(run: Path, up_to: int) -> float:
    """Training samples per second of wall time (``curve.csv``) from the run's start up to ``up_to`` steps."""
    rows = [row for row in read_curve(run) if row["timesteps"] <= up_to and math.isfinite(row["wall_s"])]
    if len(rows) < 2 or rows[-1]["wall_s"] <= rows[0]["wall_s"]:
        return math.nan
    return (rows[-1]["timesteps"] - rows[0]["timesteps"]) / (rows[-1]["wall_s"] - rows[0]["wall_s"])


def _cell(value: float, digits: int) -> str:
    return f"{value:.{digits}f}" if math.isfinite(value) else "-"


def _checkpoints(wide: CampaignEntry, reference: CampaignEntry) -> list[int]:
    """Every ``robustness_every`` steps up to where both runs have got to."""
    curves = (read_curve(run) for run in (wide.run, reference.run))
    reached = min(int(rows[-1]["timesteps"]) if rows else 0 for rows in curves)
    every = wide.defaults.robustness_every
    return list(range(every, reached + 1, every))


def _pair_rows(wide: CampaignEntry, reference: CampaignEntry) -> tuple[list[list[str]], float]:
    """The pair's table rows (their cells), and the return difference (wide minus reference) at its last
    checkpoint."""
    returns = [smoothed_curve(run) for run in (wide.run, reference.run)]
    falls = [smoothed_curve(run, column="fall_rate") for run in (wide.run, reference.run)]
    rows, difference, every = [], math.nan, wide.defaults.robustness_every
    for step in _checkpoints(wide, reference):
        w_return, r_return = (_value_at(curve, step) for curve in returns)
        w_fall, r_fall = (_value_at(curve, step) for curve in falls)
        w_table1, r_table1 = (_table1_at(run, step, every) for run in (wide.run, reference.run))
        difference = w_return - r_return
        cells = [_cell(w_return, 1), _cell(r_return, 1), _cell(w_fall, 2), _cell(r_fall, 2)]
        cells += [_cell(w_table1, 3), _cell(r_table1, 3)]
        rows.append([method_label(wide.method), str(wide.seed), millions(step), *cells])
    return rows, difference


def _speed_lines(pairs: Sequence[tuple[CampaignEntry, CampaignEntry]], out: Path) -> list[str]:
    """Each pair's samples per second over the steps compared, from the runs' own wall times."""
    lines = []
    for wide, reference in pairs:
        checkpoints = _checkpoints(wide, reference)
        if not checkpoints:
            continue
        up_to = checkpoints[-1]
        wide_speed, reference_speed = (samples_per_second(run, up_to) for run in (wide.run, reference.run))
        lines.append(
            f"- {method_label(wide.method)} seed {wide.seed}, up to {millions(up_to)}: "
            f"`{link(wide.run, out)}` {_cell(wide_speed, 0)} samples/s, "
            f"`{link(reference.run, out)}` {_cell(reference_speed, 0)} "
            "(each run's own training wall time, on the hardware of its sessions, beside whatever else ran)."
        )
    return [*lines, ""] if lines else []


def _final_evaluation_lines(
    pairs: Sequence[tuple[CampaignEntry, CampaignEntry]], evaluations: Sequence[Evaluated]
) -> list[str]:
    """Each pair's final evaluations at comparable steps, on the same robots: per case and the Table-1 mean,
    256 x 64 minus 32 x 512 with the Table-1 section's paired intervals."""
    tables, paired = [], set()
    for wide, reference in pairs:
        for first in (e for e in evaluations if e.entry.run == wide.run):
            for second in (e for e in evaluations if e.entry.run == reference.run and comparable(first, e)):
                paired.add((wide.method, wide.seed))
                who = f"{method_label(wide.method)}, seed {wide.seed}"
                heading = f"**{first.label} minus {second.label}** ({who})"
                tables += [heading, "", *pair_table(first, second, "256 x 64", "32 x 512")]
    if not tables:
        return []
    count = "One seed so far: an anecdote." if len(paired) == 1 else f"{len(paired)} seeds."
    return [
        "Final evaluations of both shapes at comparable steps (within one rollout), on the same robots, "
        f"with {section('table1')}'s paired intervals; a seed without them was not evaluated at a "
        "comparable step "
        f"in both shapes. {count}",
        "",
        *tables,
    ]


def _finding(differences: Sequence[float], step_note: str) -> str:
    """What the return differences at the last checkpoints say, over seeds."""
    mean, half, count = mean_ci(differences)
    if count == 0:
        return "No seed has reached a checkpoint in both shapes yet."
    if count == 1:
        return (f"One seed so far ({step_note}): 256 x 64 minus 32 x 512 in training return {mean:+.1f}, "
                "an anecdote; the second seed gives an interval.")  # fmt: skip
    low, high = mean - half, mean + half
    reading = ("the interval includes 0: no difference in learning per sample measured" if low <= 0 <= high
               else f"the {'256' if low > 0 else '32'}-robot shape learns more per sample")  # fmt: skip
    return (f"Over {count} seeds ({step_note}), 256 x 64 minus 32 x 512 in training return: {mean:+.1f} "
            f"[{low:+.1f}, {high:+.1f}] (95% t over seeds): {reading}.")  # fmt: skip


def rollout_shape_section(
    entries: Sequence[CampaignEntry], evaluations: Sequence[Evaluated], figures: Path, out: Path
) -> list[str]:
    """The rollout-shape section: the ``robust-256`` runs against the ``robust`` runs of their method and
    seed: training curves at the same steps, then final evaluations where both were evaluated at comparable
    steps."""
    if not any(entry.protocol == WIDE for entry in entries):
        return []
    path = figures / "rollout_shape.png"
    lines = [
        heading("rollout_shape", "Rollout shape: 256 robots x 64 steps against 32 x 512"),
        "",
        "The robust recipe with 256 robots x 64 steps per update (protocol `robust-256`) against the same "
        "recipe with 32 x 512 (`robust`), seed for seed: both update on 16,384 samples at a time, and the "
        "wider shape steps more robots at once, so trains more samples per second. It joins the comparison "
        "of methods only if it learns per sample as the 32-robot recipe does. Return and fall rate: moving "
        "averages over 50 rollouts at each step; Table-1 mean: the run's robustness row nearest the step, "
        f"within {ROW_TOLERANCE:.0%} of the steps between checkpoints. The curriculum grows with steps, so "
        "both shapes meet the same task at the same step.",
        "",
    ]
    pairs = matched_runs(entries)
    shown, differences, last_steps = [], [], []
    for wide, reference in pairs:
        rows, difference = _pair_rows(wide, reference)
        shown += rows
        if rows:
            differences.append(difference)
            last_steps.append(_checkpoints(wide, reference)[-1])
    if not shown:
        return [*lines, "No `robust-256` run has reached a checkpoint beside its 32-robot seed yet.", "",
                *figure_lines(path, out, drawn=False)]  # fmt: skip
    step_note = f"at {', '.join(sorted({millions(s) for s in last_steps}))}"
    _plot_shapes(path, pairs)
    header = ["method", "seed", "steps", "return 256 x 64", "return 32 x 512", "fall rate 256"]
    return [
        *lines,
        *table([*header, "fall rate 32", "Table-1 256", "Table-1 32"], shown),
        "",
        f"- {_finding(differences, step_note)}",
        *_speed_lines(pairs, out),
        *_final_evaluation_lines(pairs, evaluations),
        *figure_lines(path, out),
    ]


def _plot_shapes(path: Path, pairs: Sequence[tuple[CampaignEntry, CampaignEntry]]) -> None:
    """Training return and fall rate against samples: per seed one color, 256 x 64 dash-dotted, 32 x 512
    solid, each drawn up to where the wider run has got to."""
    from matplotlib.figure import Figure

    figure = Figure(figsize=(11, 4), layout="constrained")
    returns, falls = figure.subplots(1, 2)
    for index, (wide, reference) in enumerate(pairs):
        wide_steps = smoothed_curve(wide.run)[0]
        if not wide_steps.size:
            continue
        end = wide_steps[-1]
        for entry, style in ((wide, "-."), (reference, "-")):
            for axes, column in ((returns, "ep_return"), (falls, "fall_rate")):
                steps, values = smoothed_curve(entry.run, column=column)
                shown = steps <= end
                axes.plot(steps[shown] / 1e6, values[shown], style, color=f"C{index}",
                          label=f"{method_label(entry.method)} s{entry.seed}, {entry.protocol}")  # fmt: skip
    returns.set(xlabel="samples (M)", ylabel="training return (moving average)")
    falls.set(xlabel="samples (M)", ylabel="fall rate (moving average)")
    returns.legend(fontsize="small")
    for axes in (returns, falls):
        axes.grid(alpha=0.3)
    save_figure(figure, path, FIGURE_DPI)
