"""The quadruped's section of the results page: the Figure 10 analog (training return and mean terrain level
against samples) and the Table 8 analog (stepping down platforms under centroid forces), from the campaign's
``quadruped`` entries (`Go2Like-v0`, docs/go2like.md)."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np

from sb3_huri.experiments.markdown import table
from sb3_huri.runner.curve import read_curve
from study.campaign.final_evaluation import QUADRUPED_CASES
from study.campaign.queue import CampaignEntry
from study.results.early_signal import early_signal_lines
from study.results.evaluations import (
    Evaluated,
    method_label,
    pairs,
    runs_of,
    smoothed_curve,
)
from study.results.markdown import (
    difference_cell,
    figure_lines,
    link,
    millions,
    save_figure,
    verdict,
)
from study.results.methods import side_by_side_findings, side_by_side_lines
from study.results.sections import heading
from study.results.tables import case_difference, method_pair_lines, survival_cell

PAPER_TABLE8 = {
    "platform-0.40": {"huri-baseline": 65.37, "huri": 92.73},
    "platform-0.45": {"huri-baseline": 39.01, "huri": 80.55},
}
"""The paper's Table 8: success (%) stepping down a platform, PPO (baseline) and HuRi, 5 seeds."""
TABLE8_CASES = tuple(PAPER_TABLE8)


def quadruped_findings(evaluations: Sequence[Evaluated]) -> list[str]:
    """Lines of the page's findings: each quadruped pair of a method and PPO (same preset and seed, at
    comparable steps) on Table 8's platforms, paired on the same robots, and whether one seed is all; then
    each method minus HuRi where both share a PPO evaluation."""
    evaluations = [e for e in evaluations if e.entry.protocol == "quadruped"]
    lines = []
    for first, second in pairs(evaluations):
        name = method_label(first.entry.method)
        parts = []
        for case in TABLE8_CASES:
            paired = case_difference(first, second, case)
            if paired is None:
                continue
            difference, low, high = paired[2]
            reading = verdict(low, high, name, "PPO")
            parts.append(f"{case} {difference_cell(difference, low, high)}: {reading}")
        if parts:
            lines.append(
                f"- {first.entry.name} minus {second.entry.name} ({millions(first.steps)} vs "
                f"{millions(second.steps)} steps), survival on the same robots (Table 8 analog): "
                + "; ".join(parts)
                + f". One seed ({first.entry.seed}): an anecdote, no interval over seeds yet."
            )
    return [*lines, *side_by_side_findings(evaluations, TABLE8_CASES)]


def quadruped_section(
    entries: Sequence[CampaignEntry], evaluations: Sequence[Evaluated], figures: Path, out: Path
) -> list[str]:
    """The quadruped section: the quadruped's runs (Fig. 10 analog), the runs of other readings against
    HuRi and PPO at equal steps while they train, and the final evaluations (Table 8 analog)."""
    entries = [entry for entry in entries if entry.protocol == "quadruped"]
    if not entries:
        return []
    path = figures / "quadruped.png"
    lines = [
        heading("quadruped", "The quadruped (appendix A.6: Fig. 10 and Table 8 analogs)"),
        "",
        "`Go2Like-v0` on legged_gym's task (docs/go2like.md). Training return and the robots' mean terrain "
        "level against samples, a moving average over 50 rollouts; one line per run.",
        "",
    ]
    curves = {run: run_entries[0] for run, run_entries in runs_of(entries).items() if read_curve(run)}
    if curves:
        _plot_quadruped(path, curves)
        lines += figure_lines(path, out)
    else:
        lines += ["No quadruped run has a learning curve yet.", "", *figure_lines(path, out, drawn=False)]
    return [*lines, *early_signal_lines(entries, out), *_table8(evaluations, out)]


def _label(entry: CampaignEntry) -> str:
    """The run's name on the figure: its entry's name without the seed's suffix."""
    return entry.name.rsplit("-s", 1)[0]


def _plot_quadruped(path: Path, curves: dict[Path, CampaignEntry]) -> None:
    """Two panels: return and mean terrain level (where the run is on tiles) against samples."""
    from matplotlib.figure import Figure

    figure = Figure(figsize=(11, 4), layout="constrained")
    returns, levels = figure.subplots(1, 2)
    on_tiles = False
    for run, entry in curves.items():
        style = {"linestyle": "-" if entry.method == "huri" else "--"}
        steps, values = smoothed_curve(run)
        line = returns.plot(steps / 1e6, values, label=_label(entry), **style)[0]
        level_steps, level = smoothed_curve(run, column="terrain_level")
        if len(level_steps):
            levels.plot(level_steps / 1e6, level, color=line.get_color(), label=_label(entry), **style)
            on_tiles = True
    if not on_tiles:
        levels.text(0.5, 0.5, "no run on terrains yet", ha="center", va="center", transform=levels.transAxes)
    returns.set(xlabel="samples (M)", ylabel="training return (A)")
    levels.set(xlabel="samples (M)", ylabel="mean terrain level (B)")
    returns.legend(fontsize="small")
    save_figure(figure, path, 110)


def _table8(evaluations: Sequence[Evaluated], out: Path) -> list[str]:
    """Each evaluated quadruped agent's survival per case with its 95% interval, beside the paper's."""
    shown = [e for e in evaluations if e.entry.protocol == "quadruped"]
    if not shown:
        return ["No quadruped agent has its final evaluation yet (Table 8 analog).", ""]
    walking = [case for case in QUADRUPED_CASES if "@" in case]
    lines = [
        "Survival per case with its 95% Wilson interval, and the mean forward velocity (m/s) under each "
        "walking case's command:",
        "",
    ]
    rows = []
    for evaluated in shown:
        cells = [f"[{evaluated.label}]({link(evaluated.path, out)})"]
        cells += [survival_cell(evaluated, case) for case in QUADRUPED_CASES]
        for case in walking:
            vx = evaluated.metric(case, "vx")
            cells.append("-" if not np.isfinite(vx) else f"{vx:.2f}")
        rows.append(cells)
    lines += table(["agent", *QUADRUPED_CASES, *(f"vx, {case}" for case in walking)], rows)
    paper = ", ".join(
        f"{case}: PPO {values['huri-baseline']:.0f}%, HuRi {values['huri']:.0f}%"
        for case, values in PAPER_TABLE8.items()
    )
    lines += ["", f"The paper's Table 8 (Go2 in Isaac Gym, 5 seeds): {paper}.", ""]
    for first, second in pairs(shown):
        lines += method_pair_lines(first, second, QUADRUPED_CASES)
    return [*lines, *side_by_side_lines(shown, QUADRUPED_CASES)]
