"""The IQR band in training, for the results page: which risk levels each run's rollouts used.

The band's shares, thresholds and mean risk level come from ``curve.csv`` (a row per rollout, written since
the curve kept them: earlier rows are blank there).
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from sb3_huri.experiments.markdown import table
from sb3_huri.runner.curve import read_curve
from study.campaign.queue import CampaignEntry
from study.results.evaluations import FIGURE_DPI, method_label, runs_of
from study.results.markdown import figure_lines, link, save_figure
from study.results.sections import heading

WINDOW_STEPS = 1_000_000
"""The curve's figures at a step are averaged over the rollouts of this many steps up to it."""
SHARES = ("iqr_below", "iqr_within", "iqr_above")


def band_section(entries: Sequence[CampaignEntry], figures: Path, out: Path) -> list[str]:
    """The section: per run with a quantile critic, its rollouts' risk levels (a table and a figure)."""
    path = figures / "band.png"
    lines = [
        heading("band", "The IQR band in training: the risk levels in use"),
        "",
        "Each rollout's share of states below, within and above the IQR band (seeking, neutral, averse: "
        "`beta_IQR` = -1, 0, +1), the band's thresholds and the mean `beta`, from `curve.csv` (runs trained "
        "before the curve kept them have no such rows). `huri` reads the band `[0.3, 0.7]` in units of the "
        "normalized return, as printed; `huri-percentile` puts it at the 30th and 70th percentiles of the "
        "critic's own IQR over recent rollouts ([huri.md](huri.md#our-reading-of-the-paper-and-why)). "
        f"Figures averaged over the rollouts of the last {WINDOW_STEPS / 1e6:.0f}M steps.",
        "",
    ]
    runs = {run: run_entries for run, run_entries in runs_of(entries).items() if _risk_rows(run)}
    if not runs:
        return [*lines, "No run has logged its risk levels yet.", "", *figure_lines(path, out, drawn=False)]
    rows = []
    for run, run_entries in runs.items():
        curve = _risk_rows(run)
        last = window_means(curve, curve[-1]["timesteps"])
        whole = {column: float(np.mean([row[column] for row in curve])) for column in SHARES}
        label = f"`{link(run, out)}` ({method_label(run_entries[0].method)})"
        band = f"({last['iqr_t_min']:.3f}, {last['iqr_t_max']:.3f})"
        cells = [label, f"{int(curve[-1]['timesteps']):,}", shares_cell(last), shares_cell(whole), band]
        rows.append([*cells, f"{last['risk_mean']:+.2f}", number_cell(last["risk_rnd_mean"], "+.2f")])
    _plot(path, runs)
    header = ["run", "steps", "seeking / neutral / averse (last 1M)", "over the whole run"]
    header += ["band (t_min, t_max)", "mean beta", "its RND part"]
    return [*lines, *table(header, rows), "", *figure_lines(path, out)]


def window_means(curve: list[dict[str, float]], step: float) -> dict[str, float]:
    """The curve's columns averaged over its rows in ``(step - WINDOW_STEPS, step]`` (NaN where none)."""
    rows = [row for row in curve if step - WINDOW_STEPS < row["timesteps"] <= step]
    if not rows:
        return {}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # a column without a value in the window: NaN
        return {key: float(np.nanmean([row[key] for row in rows])) for key in rows[0]}


def _risk_rows(run: Path) -> list[dict[str, float]]:
    return [row for row in read_curve(run) if math.isfinite(row["iqr_below"])]


def shares_cell(figures: dict[str, float]) -> str:
    if not figures or not all(math.isfinite(figures.get(column, math.nan)) for column in SHARES):
        return "-"
    return " / ".join(f"{figures[column]:.2f}" for column in SHARES)


def number_cell(value: float, fmt: str) -> str:
    return format(value, fmt) if math.isfinite(value) else "-"


def _plot(path: Path, runs: dict[Path, list[CampaignEntry]]) -> None:
    """Per run: the three shares against steps, and the mean beta."""
    from matplotlib.figure import Figure

    figure = Figure(figsize=(9, 2.4 * len(runs) + 0.6), layout="constrained")
    grid = figure.subplots(len(runs), 1, squeeze=False)[:, 0]
    for axes, (run, run_entries) in zip(grid, runs.items(), strict=True):
        rows = _risk_rows(run)
        steps = np.array([row["timesteps"] for row in rows]) / 1e6
        for column, label, color in zip(
            SHARES, ("seeking", "neutral", "averse"), ("tab:green", "tab:gray", "tab:red"), strict=True
        ):
            axes.plot(steps, _smooth([row[column] for row in rows]), color=color, lw=1.2, label=label)
        axes.plot(
            steps,
            _smooth([row["risk_mean"] for row in rows]),
            color="black",
            lw=1,
            ls="--",
            label="mean beta",
        )
        axes.set_ylim(-1.05, 1.05)
        axes.grid(alpha=0.3)
        axes.set_title(f"{', '.join(e.name for e in run_entries)} ({run_entries[0].method})", fontsize=9)
        axes.set_ylabel("share / beta")
    grid[-1].set_xlabel("environment steps (millions)")
    grid[0].legend(fontsize=7, ncol=4, loc="lower right")
    save_figure(figure, path, FIGURE_DPI)


def _smooth(values: Sequence[float], window: int = 9) -> np.ndarray:
    """A centred moving average over `window` rollouts (shorter at the ends)."""
    from scipy.ndimage import uniform_filter1d

    return uniform_filter1d(np.asarray(values, dtype=float), size=min(window, len(values)), mode="nearest")
