"""The IQR band in training, for the results page: which risk levels each run's rollouts used (its own
section), and the runs with the percentile band against the literal HuRi and PPO of their protocol and seed
at equal steps (the early signal: Zerith-1's in the robustness section, the quadruped's in its own).

The band's shares, thresholds and mean risk level come from ``curve.csv`` (a row per rollout, written since
the curve kept them: earlier rows are blank there); the robustness rows from ``robustness.csv``.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from sb3_huri.experiments.markdown import table
from sb3_huri.huri import METHODS
from sb3_huri.runner.curve import read_curve
from sb3_huri.runner.robustness import read_rows
from study.campaign.queue import CampaignEntry
from study.results.evaluations import BASELINE, FIGURE_DPI, method_label, runs_of
from study.results.markdown import figure_lines, link, millions, save_figure
from study.results.sections import heading

PERCENTILE_METHODS = tuple(name for name, preset in METHODS.items() if preset.iqr_band == "percentile")
"""The methods whose band follows the critic's own IQR."""
LITERAL = "huri"
"""The method of the band as printed, which the percentile band's runs are held against."""
WINDOW_STEPS = 1_000_000
"""The curve's figures at a step are averaged over the rollouts of this many steps up to it."""
SHARES = ("iqr_below", "iqr_within", "iqr_above")


def band_section(entries: Sequence[CampaignEntry], figures: Path, out: Path) -> list[str]:
    """The section: per run with a quantile critic, its rollouts' risk levels (a table and a figure), and
    per percentile-band run the comparison at equal steps."""
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
        last = _window(curve, curve[-1]["timesteps"])
        whole = {column: float(np.mean([row[column] for row in curve])) for column in SHARES}
        label = f"`{link(run, out)}` ({method_label(run_entries[0].method)})"
        band = f"({last['iqr_t_min']:.3f}, {last['iqr_t_max']:.3f})"
        cells = [label, f"{int(curve[-1]['timesteps']):,}", _shares(last), _shares(whole), band]
        rows.append([*cells, f"{last['risk_mean']:+.2f}", _number(last["risk_rnd_mean"], "+.2f")])
    _plot(path, runs)
    header = ["run", "steps", "seeking / neutral / averse (last 1M)", "over the whole run"]
    header += ["band (t_min, t_max)", "mean beta", "its RND part"]
    return [*lines, *table(header, rows), "", *figure_lines(path, out)]


def early_signal_lines(entries: Sequence[CampaignEntry], out: Path) -> list[str]:
    """Each percentile-band run beside the literal HuRi and PPO runs of its protocol, seed and preset at
    equal steps: the early signal while it trains (Zerith-1's beside the robustness curves;
    the quadruped's in its section). The last figure is the Table-1 mean of the robustness rows for Zerith-1,
    the robots' mean terrain level for the quadruped (whose robustness, the platforms, is evaluated at the
    end only)."""
    lines = []
    for run, run_entries in runs_of(entries).items():
        first = run_entries[0]
        own = read_curve(run)
        marks = _marks(run, own)
        if first.method not in PERCENTILE_METHODS or not marks:
            continue
        peers = {
            method: next(
                (e.run for e in entries if e.method == method and _same_recipe(e, first) and e.run != run),
                None,
            )
            for method in (LITERAL, BASELINE)
        }
        on_tiles = first.protocol == "quadruped"
        progress = (
            "the robots' mean terrain level (the curriculum's, from the curve)"
            if on_tiles
            else "the Table-1 mean of the robustness rows (50 robots per case)"
        )
        lines += [
            f"**{', '.join(e.name for e in run_entries)}** against "
            + " and ".join(f"`{link(peer, out)}` ({method_label(m)})" for m, peer in peers.items() if peer)
            + f" at equal steps: training return, episode length (steps of 20 ms), fall rate and {progress}, "
            "then the percentile run's band shares.",
            "",
        ]
        columns = [("ep_return", ".0f"), ("ep_len", ".0f"), ("fall_rate", ".2f")]
        if on_tiles:
            columns.append(("terrain_level", ".2f"))
        curves = {m: read_curve(peer) if peer else [] for m, peer in peers.items()}
        robustness = {m: read_rows(peer) if peer else {} for m, peer in peers.items()}
        own_rows = read_rows(run)
        rows = []
        for step in marks:
            figures = [_window(own, step)] + [_window(curves[m], step) for m in peers]
            cells = [
                " / ".join(_number(f.get(column, math.nan), fmt) for f in figures) for column, fmt in columns
            ]
            if not on_tiles:
                table1 = [_row_near(own_rows, step)] + [_row_near(robustness[m], step) for m in peers]
                cells.append(" / ".join(_table1_cell(row, step) for row in table1))
            rows.append([f"{step / 1e6:.0f}M", *cells, _shares(figures[0])])
        header = ["steps", "return: percentile / HuRi / PPO", "length", "fall rate"]
        header += ["terrain level" if on_tiles else "Table-1 mean (rows)", "seeking / neutral / averse"]
        lines += [*table(header, rows), ""]
    return lines


def _same_recipe(entry: CampaignEntry, other: CampaignEntry) -> bool:
    return (entry.protocol, entry.seed, entry.conf, entry.hyperparams) == (
        other.protocol,
        other.seed,
        other.conf,
        other.hyperparams,
    )


def _marks(run: Path, curve: list[dict[str, float]]) -> list[int]:
    """The steps to compare at: the run's robustness rows, else every 5M steps of its curve."""
    rows = [step for step in read_rows(run) if step >= WINDOW_STEPS]
    if rows:
        return [int(round(step / WINDOW_STEPS) * WINDOW_STEPS) for step in rows]
    if not curve:
        return []
    return list(range(5_000_000, int(curve[-1]["timesteps"]) + 1, 5_000_000))


def _row_near(rows: dict[int, dict[str, str]], step: int) -> dict[str, str] | None:
    """The robustness row nearest `step` within half the rows' period (5M), if any."""
    near = [s for s in rows if abs(s - step) < 2_500_000]
    return rows[min(near, key=lambda s: abs(s - step))] if near else None


def _table1_cell(row: dict[str, str] | None, step: int) -> str:
    """A row's Table-1 mean, with the row's own step where it is more than half a million from `step`."""
    if row is None:
        return "-"
    cell = f"{float(row['table1_mean']):.3f}"
    own = int(row["timesteps"])
    return cell if abs(own - step) <= WINDOW_STEPS // 2 else f"{cell} ({millions(own)})"


def _window(curve: list[dict[str, float]], step: float) -> dict[str, float]:
    """The curve's columns averaged over its rows in ``(step - WINDOW_STEPS, step]`` (NaN where none)."""
    rows = [row for row in curve if step - WINDOW_STEPS < row["timesteps"] <= step]
    if not rows:
        return {}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # a column without a value in the window: NaN
        return {key: float(np.nanmean([row[key] for row in rows])) for key in rows[0]}


def _risk_rows(run: Path) -> list[dict[str, float]]:
    return [row for row in read_curve(run) if math.isfinite(row["iqr_below"])]


def _shares(figures: dict[str, float]) -> str:
    if not figures or not all(math.isfinite(figures.get(column, math.nan)) for column in SHARES):
        return "-"
    return " / ".join(f"{figures[column]:.2f}" for column in SHARES)


def _number(value: float, fmt: str) -> str:
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
