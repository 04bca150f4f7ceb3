"""The early signal, for the results page: each run of a reading other than the paper's HuRi and PPO (the
percentile band, the risk-neutral critic, the ablations) beside the HuRi and PPO runs of its protocol, seed
and preset at equal steps, while it trains: Zerith-1's in the robustness section, the quadruped's in its own.

The training figures come from ``curve.csv``, the Table-1 means from ``robustness.csv``; a method that reads
the IQR band also shows the share of its rollouts' states below, within and above it.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path

from sb3_huri.experiments.markdown import table
from sb3_huri.huri import METHODS
from sb3_huri.runner.curve import read_curve
from sb3_huri.runner.robustness import read_rows
from study.campaign.queue import CampaignEntry
from study.results.band import WINDOW_STEPS, number_cell, shares_cell, window_means
from study.results.evaluations import BASELINE, method_label, runs_of
from study.results.markdown import link, millions
from study.results.methods import REFERENCE

ROW_PERIOD = 5_000_000
"""The robustness rows' period: a peer's row counts at a step within half of it."""


def early_signal_lines(entries: Sequence[CampaignEntry], out: Path) -> list[str]:
    """Per run of another reading, a table at each of its robustness rows (the quadruped's: every 5M steps
    of its curve) of the training return, episode length, fall rate and the Table-1 mean of the robustness
    rows (the quadruped's: the robots' mean terrain level, its robustness being evaluated at the end
    only), its own figure first, then HuRi's and PPO's."""
    lines = []
    for run, run_entries in runs_of(entries).items():
        first = run_entries[0]
        own = read_curve(run)
        marks = _marks(run, own)
        if first.method in (REFERENCE, BASELINE) or not marks:
            continue
        peers = {
            method: next(
                (e.run for e in entries if e.method == method and _same_recipe(e, first) and e.run != run),
                None,
            )
            for method in (REFERENCE, BASELINE)
        }
        on_tiles = first.protocol == "quadruped"
        with_band = METHODS[first.method].use_iqr
        progress = (
            "the robots' mean terrain level (the curriculum's, from the curve)"
            if on_tiles
            else "the Table-1 mean of the robustness rows (50 robots per case)"
        )
        lines += [
            f"**{', '.join(e.name for e in run_entries)}** ({first.method}) against "
            + " and ".join(f"`{link(peer, out)}` ({method_label(m)})" for m, peer in peers.items() if peer)
            + f" at equal steps: training return, episode length (steps of 20 ms), fall rate and {progress}"
            + (", then its band shares." if with_band else "."),
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
            figures = [window_means(own, step)] + [window_means(curves[m], step) for m in peers]
            cells = [
                " / ".join(number_cell(f.get(column, math.nan), fmt) for f in figures)
                for column, fmt in columns
            ]
            if not on_tiles:
                table1 = [_row_near(own_rows, step)] + [_row_near(robustness[m], step) for m in peers]
                cells.append(" / ".join(_table1_cell(row, step) for row in table1))
            if with_band:
                cells.append(shares_cell(figures[0]))
            rows.append([f"{step / 1e6:.0f}M", *cells])
        header = ["steps", f"return: {first.method} / HuRi / PPO", "length", "fall rate"]
        header.append("terrain level" if on_tiles else "Table-1 mean (rows)")
        if with_band:
            header.append("seeking / neutral / averse")
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
    return list(range(ROW_PERIOD, int(curve[-1]["timesteps"]) + 1, ROW_PERIOD))


def _row_near(rows: dict[int, dict[str, str]], step: int) -> dict[str, str] | None:
    """The robustness row nearest `step` within half the rows' period, if any."""
    near = [s for s in rows if abs(s - step) < ROW_PERIOD // 2]
    return rows[min(near, key=lambda s: abs(s - step))] if near else None


def _table1_cell(row: dict[str, str] | None, step: int) -> str:
    """A row's Table-1 mean, with the row's own step where it is more than half a million from `step`."""
    if row is None:
        return "-"
    cell = f"{float(row['table1_mean']):.3f}"
    own = int(row["timesteps"])
    return cell if abs(own - step) <= WINDOW_STEPS // 2 else f"{cell} ({millions(own)})"
