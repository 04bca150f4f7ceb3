"""One run's robustness curve as a figure, with the runs forked from it and other methods' runs beside it.

The campaign's results page draws every run's Table-1 mean on one axis
(``study.results``); this figure looks into one run: each Table-1 case,
``side-impact``, the Table-1 mean with its 95% Wilson band and the curriculum's scale, and the Table-1 mean of
forks (copies of the run trained on from one of its checkpoints, with a change) and of other methods' runs
trained with the same recipe. ``study/scripts/robustness_curve.py --plot`` draws it.
"""

from __future__ import annotations

import csv
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from sb3_huri.experiments.statistics import wilson_interval
from sb3_huri.runner.evaluation import TABLE1_SCENARIOS
from sb3_huri.runner.robustness import read_rows

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

FORK_COLORS = ("tab:red", "tab:purple", "tab:olive", "teal", "darkgoldenrod", "magenta")
"""The colors of the forks' lines, in order (taken again from the first past the last)."""
VERSUS_COLORS = ("tab:blue", "tab:green", "tab:brown")
"""The colors of other methods' lines (`versus`), in order."""


def fork_own_rows(
    run_rows: dict[int, dict[str, str]], fork_rows: dict[int, dict[str, str]]
) -> list[tuple[int, dict[str, str]]]:
    """A fork's own rows, from the last row it shares with its run on: a row is shared when the run has
    the same row at the same step (the fork's `robustness.csv` starts as a copy of the run's). Rows at the
    same step but evaluated differently are the fork's own: after the fork both go on from the same step
    count, so their checkpoints carry the same step numbers."""
    rows = list(fork_rows.items())
    first = next((i for i, (s, r) in enumerate(rows) if run_rows.get(s) != r), len(rows))
    return rows[max(first - 1, 0) :] if first < len(rows) else []


def _mean_line(rows: list[dict[str, str]]) -> tuple[np.ndarray, np.ndarray]:
    """The Table-1 mean of `rows` by training steps in millions, as a plot's x and y."""
    steps = np.array([int(r["timesteps"]) for r in rows]) / 1e6
    return steps, np.array([float(r["table1_mean"]) for r in rows])


def _draw_others(axes: Axes, run: Path, forks: tuple[Path, ...], versus: tuple[Path, ...]) -> None:
    """The Table-1 mean of each fork over its own rows (solid) and of each other method's run (dashed)."""
    run_rows = read_rows(run)
    for index, fork in enumerate(forks):
        color = FORK_COLORS[index % len(FORK_COLORS)]
        own = fork_own_rows(run_rows, read_rows(fork))
        if not own:
            raise ValueError(f"{fork} has no evaluated checkpoint beyond those of {run} (robustness.csv)")
        label = f"{fork.name}: Table-1 mean"
        axes.plot(*_mean_line([r for _, r in own]), "-", color=color, lw=2.5, label=label)
    for index, other in enumerate(versus):
        other_rows = list(read_rows(other).values())
        if not other_rows:
            raise ValueError(f"{other} has no evaluated checkpoint to plot (robustness.csv)")
        axes.plot(*_mean_line(other_rows), "--", lw=2.5,
                  color=VERSUS_COLORS[index % len(VERSUS_COLORS)],
                  label=f"{other.parent.name}/{other.name}: Table-1 mean")  # fmt: skip


def plot_curve(run: Path, path: Path, forks: tuple[Path, ...] = (), versus: tuple[Path, ...] = ()) -> Figure:
    """The robustness curve as a figure: each Table-1 case and `side-impact` by training steps, the Table-1
    mean with its 95% Wilson band, and the curriculum's scale (`curve.csv`) on a second axis. Each run of
    `forks` (a copy of `run` trained on from one of its checkpoints) adds its Table-1 mean over its own
    rows (`fork_own_rows`); each run of `versus` (another method's run, e.g. PPO with the same recipe) its
    Table-1 mean over all its rows, dashed, labelled `<algo>/<run>`. Returns the figure it saved to `path`."""
    from matplotlib.figure import Figure

    rows = list(read_rows(run).values())
    if not rows:
        raise ValueError(f"{run} has no evaluated checkpoint to plot (robustness.csv)")
    steps, mean = _mean_line(rows)
    figure = Figure(figsize=(8, 5.2), layout="constrained")
    axes = figure.add_subplot()
    for case in (*TABLE1_SCENARIOS, "side-impact"):
        style = ":" if case == "side-impact" else "-"
        axes.plot(steps, [float(r[case]) for r in rows], style, lw=1, alpha=0.7, label=case)
    cases = len(TABLE1_SCENARIOS)
    bands = [wilson_interval(m, int(r["episodes"]) * cases) for m, r in zip(mean, rows, strict=True)]
    axes.fill_between(steps, [b[0] for b in bands], [b[1] for b in bands], color="black", alpha=0.15)
    axes.plot(steps, mean, "k-", lw=2.5, label="Table-1 mean (95% band)")
    _draw_others(axes, run, forks, versus)
    axes.set_xlabel("environment steps (millions)")
    axes.set_ylabel("survival rate (20-s episodes)")
    axes.set_ylim(-0.02, 1.02)
    axes.grid(alpha=0.3)
    with (run / "curve.csv").open() as file:
        curve = [(int(r["timesteps"]) / 1e6, float(r["scale"])) for r in csv.DictReader(file)]
    scale_axes = axes.twinx()
    scale_axes.plot([c[0] for c in curve], [c[1] for c in curve], color="tab:gray", lw=1, ls="--")
    scale_axes.set_ylabel("curriculum scale (dashed)", color="tab:gray")
    scale_axes.set_ylim(-0.02, 1.02)
    figure.legend(fontsize=7, loc="outside lower center", ncol=4)
    axes.set_title(f"{run.name}: survival under the paper's test disturbances, by training steps")
    figure.savefig(path, dpi=110)
    return figure
