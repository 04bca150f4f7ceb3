"""Zerith-1's survival over the force's magnitude on the results page: each evaluated agent's survival in the
Table-1 and Fig. 4 cases from a tenth to one and a half of the paper's disturbance, the scale at which it
falls to 50%, and every HuRi-PPO pair's difference on the same robots at each scale, under both readings of
the forces on the hands and feet and both hold times of a push (``study.analyses
.force_magnitude`` measures them: ``study.scripts.force_magnitude``)."""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from sb3_huri.experiments.markdown import table
from study.analyses.force_magnitude import (
    CASES,
    FIG4_CASES,
    HEADLINE,
    NOMINAL_READINGS,
    PAPER_SCALE,
    READINGS,
    Reading,
    agent_record,
    half_survival_scale,
    paired_curve,
    scale_cell,
    survival_curve,
    survived,
    table1_difference,
    table1_robot_means,
)
from study.results.evaluations import (
    BASELINE,
    FIGURE_DPI,
    Evaluated,
    method_label,
    pairs,
)
from study.results.markdown import (
    difference_cell,
    figure_lines,
    save_figure,
    verdict,
)
from study.results.sections import heading

FIGURE = "force_magnitude.png"
PER_BODY, SHORT_PUSH = Reading(per_body=True), Reading(hold_steps=1)
"""The headline reading with a force per hand / foot, and with 0.02-s pushes."""


def force_magnitude_section(evaluations: Sequence[Evaluated], figures: Path, out: Path) -> list[str]:
    """The force-magnitude section: the 50% scales of every measured agent, its Table-1 mean at 1x under each
    reading measured, each pair's differences under each reading, and the figure of the curves and the pairs'
    differences."""
    path = figures / FIGURE
    lines = [
        heading("force_magnitude", "Survival over force magnitude"),
        "",
        "Each evaluated Zerith-1 agent (the checkpoint of its final evaluation, measured by the campaign "
        "after that evaluation or by `study/scripts/force_magnitude.py`) in the six Table-1 cases and "
        "Fig. 4's load, friction and load-friction cases, with the disturbance at s times the paper's: in "
        "Table 1 the force's magnitude (U[0, 100 s] N redrawn every 0.1 s; U[150 s, 200 s] N every 2 s), "
        "Table 5's test load, friction and CoM ranges kept; in Fig. 4's cases the force (U[0, 100 s] N "
        "held 0.5 s), the load's range ([-3 s, 8 s] kg) and the friction's factor from the nominal 1 raised "
        "to the power s ([0.1^s, 2^s], a log scale: scaled linearly it would reach 0 at 1.11x). Robot i is "
        "seeded 2000 + i: the first robots of the final evaluations, the same for every agent, scale and "
        "reading; one 20-s episode at 1 m/s each, success = no fall.",
        "",
        f"**Headline reading: {HEADLINE.label}**, Table 5's test ranges: the env's default, the reading of "
        "every other section. The paper says neither whether the force on the hands (feet) is one vector "
        "for the pair or one per hand (foot), nor how long a sudden push lasts; the pairs below are measured "
        "under both readings and with pushes of one control step (0.02 s) too, and **which agent survives "
        "more can depend on the reading**.",
        "",
    ]
    measured = [(e, agent_record(e.entry.run, e.steps)) for e in evaluations]
    records = {id(e): record for e, record in measured if record is not None}
    shown = [e for e in evaluations if id(e) in records]
    if not shown:
        lines += ["No agent is measured yet (`study/scripts/force_magnitude.py`).", ""]
        return [*lines, *figure_lines(path, out, drawn=False)]
    lines += _half_table(shown, records)
    lines += _readings_table(shown, records)
    lines += _substitutes(evaluations, records)
    found = [(a, b) for a, b in pairs(evaluations) if id(a) in records and id(b) in records]
    for first, second in found:
        lines += _pair_lines(first, second, records[id(first)], records[id(second)])
    if not found:
        lines += ["No HuRi-PPO pair is measured yet.", ""]
    _plot(path, shown, records, found)
    return [*lines, *figure_lines(path, out)]


def _scales(records: Sequence[dict[str, Any]]) -> list[float]:
    """Every scale measured under the headline, in order."""
    found = {s for r in records for case in CASES for s in survived(r, HEADLINE, case)}
    return sorted(found)


def _half_table(shown: Sequence[Evaluated], records: dict[int, dict[str, Any]]) -> list[str]:
    """The scale at which each agent's headline survival falls to 50%, per case."""
    scales = _scales([records[id(e)] for e in shown])
    steps = np.diff(scales)
    resolution = ", ".join(f"{s:g}" for s in scales)
    spacing = f"{steps.min():.2g}x to {steps.max():.2g}x apart" if steps.size else "one scale"
    robots = sorted({records[id(e)]["settings"]["robots"] for e in shown})
    lines = [
        f"**Where survival falls to 50%** (headline reading; {', '.join(map(str, robots))} robots per case "
        f"and scale): the scale s, times the paper's disturbance, at which survival first falls below 50% "
        f"going up the scales, interpolated linearly between the two measured scales around it. Scales "
        f"measured: {resolution} ({spacing}: the resolution); `> {max(scales):g}x`: never below 50%; "
        f"`< {min(scales):g}x`: below 50% already at the smallest. Beside it, survival at the paper's "
        "1x.",
        "",
    ]
    rows = []
    for evaluated in shown:
        record = records[id(evaluated)]
        cells = [evaluated.label, f"{record['steps']:,}"]
        for case in CASES:
            at_paper = survived(record, HEADLINE, case).get(PAPER_SCALE)
            cells.append(_half(record, case) + (f" ({at_paper.mean():.2f})" if at_paper is not None else ""))
        rows.append(cells)
    return [*lines, *table(["agent", "measured at", *CASES], rows), ""]


def _readings_table(shown: Sequence[Evaluated], records: dict[int, dict[str, Any]]) -> list[str]:
    """Each agent's Table-1 mean at 1x under every reading measured: how much the reading moves it."""
    readings = (*READINGS, *NOMINAL_READINGS)
    means = {
        id(e): [table1_robot_means(records[id(e)], reading, PAPER_SCALE) for reading in readings]
        for e in shown
    }
    agents = [e for e in shown if sum(m is not None for m in means[id(e)]) > 1]
    if not agents:
        return []
    rows = [[e.label, *("-" if m is None else f"{m.mean():.3f}" for m in means[id(e)])] for e in agents]
    return [
        "**Every reading, each agent** (the Table-1 mean at 1x, on the same robots as above; `-`: not "
        "measured): " + "; ".join(f"`{reading.key}`: {reading.label}" for reading in readings) + ".",
        "",
        *table(["agent", *(f"`{reading.key}`" for reading in readings)], rows),
        "",
    ]


def _substitutes(evaluations: Sequence[Evaluated], records: dict[int, dict[str, Any]]) -> list[str]:
    """Which agents were measured at another step than their evaluation's, and which not at all."""
    lines = []
    for e in evaluations:
        record = records.get(id(e))
        if record is None:
            lines.append(f"- {e.label}: not measured.")
        elif record["steps"] != e.steps:
            lines.append(
                f"- {e.label}: its checkpoint is not held; measured at {record['steps']:,} steps instead."
            )
    return [*lines, ""] if lines else []


def _pair_lines(first: Evaluated, second: Evaluated, a: dict[str, Any], b: dict[str, Any]) -> list[str]:
    """A pair's Table-1 mean at 1x under each reading measured, and its differences per case."""
    name, other = method_label(first.entry.method), method_label(second.entry.method)
    lines = [
        f"**{first.label} minus {second.label}** ({first.entry.protocol}, seed {first.entry.seed}; measured "
        f"at {a['steps']:,} and {b['steps']:,} steps, on the same robots)",
        "",
    ]
    rows = []
    ahead: dict[str, list[str]] = {}  # by the paper's forces read each way: who is ahead (point estimates)
    for reading in (*READINGS, *NOMINAL_READINGS):
        means = table1_robot_means(a, reading, PAPER_SCALE), table1_robot_means(b, reading, PAPER_SCALE)
        if means[0] is None or means[1] is None:
            continue
        mean, low, high = table1_difference(a, b, reading)
        if reading in READINGS:
            ahead.setdefault(name if mean > 0 else other if mean < 0 else "neither", []).append(reading.key)
        cells = [reading.label, f"{means[0].mean():.3f}", f"{means[1].mean():.3f}"]
        rows.append([*cells, difference_cell(mean, low, high), verdict(low, high, name, other)])
    header = ["reading, Table-1 mean at 1x", name, other, "difference [95%, t over robots]"]
    lines += table([*header, "who survives more"], rows)
    if len(ahead.keys() - {"neither"}) > 1:
        where = "; ".join(f"{who} ahead under {', '.join(keys)}" for who, keys in ahead.items())
        lines += ["", f"**The order depends on the reading** (Table-1 mean at 1x, point estimates): {where}."]
    elif ahead:
        lines += ["", "The same order under every reading of the test robot measured (point estimates)."]
    rows = []
    for case in CASES:
        curve = paired_curve(survived(a, HEADLINE, case), survived(b, HEADLINE, case))
        if not curve:
            continue
        halves = [_half(record, case) for record in (a, b)]
        at_paper = next((row for row in curve if row[0] == PAPER_SCALE), None)
        largest = max(curve, key=lambda row: (abs(row[1]), -row[0]))
        cells = [
            difference_cell(*at_paper[1:]) if at_paper else "-",
            f"{largest[0]:g}x: {difference_cell(*largest[1:])}",
            *(_reading_cell(a, b, reading, case) for reading in (PER_BODY, SHORT_PUSH)),
        ]
        rows.append([case, *halves, *cells])
    header = ["case", f"{name} 50%", f"{other} 50%", "difference at 1x [95%]"]
    header += ["largest difference: at, [95%]", "at 1x, a force per hand / foot", "at 1x, 0.02-s pushes"]
    return [*lines, "", *table(header, rows), ""]


def _half(record: dict[str, Any], case: str) -> str:
    """The headline's 50% scale of ``case`` as a cell ('-' if unmeasured)."""
    xs, shares, _ = survival_curve(survived(record, HEADLINE, case))
    return scale_cell(half_survival_scale(xs, shares), xs) if xs.size else "-"


def _reading_cell(a: dict[str, Any], b: dict[str, Any], reading: Reading, case: str) -> str:
    """The difference at 1x under ``reading`` where it changes the case ('-' where it does not)."""
    if reading.canonical(case) == HEADLINE:
        return "-"
    rows = paired_curve(survived(a, reading, case), survived(b, reading, case))
    at_paper = next((row for row in rows if row[0] == PAPER_SCALE), None)
    return difference_cell(*at_paper[1:]) if at_paper else "not measured"


def _plot(
    path: Path,
    shown: Sequence[Evaluated],
    records: dict[int, dict[str, Any]],
    found: Sequence[tuple[Evaluated, Evaluated]],
) -> None:
    """Top: survival per case against the scale, one line per agent (headline reading). Bottom: each pair's
    difference per case, its 95% band under the headline, the other readings as thinner lines."""
    from matplotlib.figure import Figure

    columns = 3
    rows = math.ceil(len(CASES) / columns)
    figure = Figure(figsize=(12, 6.2 * rows / 1.5 + 1), layout="constrained")
    panels = figure.subplots(2 * rows, columns, squeeze=False, sharex=True)
    colors = [f"C{index % 10}" for index in range(len(shown))]
    for index, case in enumerate(CASES):
        row, column = divmod(index, columns)
        curves, differences = panels[row][column], panels[rows + row][column]
        for color, evaluated in zip(colors, shown, strict=True):
            xs, shares, _ = survival_curve(survived(records[id(evaluated)], HEADLINE, case))
            style = "--" if evaluated.entry.method == BASELINE else "-"
            curves.plot(xs, shares, style, marker=".", color=color, lw=1.2, label=evaluated.label)
        curves.axhline(0.5, color="grey", lw=0.6, ls=":")
        curves.set_ylim(-0.03, 1.03)
        curves.set_title(f"{case}{' (robot perturbed too)' if case in FIG4_CASES else ''}", fontsize=9)
        for pair_index, (first, second) in enumerate(found):
            color = f"C{(len(shown) + pair_index) % 10}"
            a, b = records[id(first)], records[id(second)]
            for reading, style in ((HEADLINE, "-"), (PER_BODY, "--"), (SHORT_PUSH, ":")):
                if reading != HEADLINE and reading.canonical(case) == HEADLINE:
                    continue
                paired = paired_curve(survived(a, reading, case), survived(b, reading, case))
                if not paired:
                    continue
                xs, diff, low, high = (np.array(values) for values in zip(*paired, strict=True))
                width = 1.4 if reading == HEADLINE else 1.0
                differences.plot(xs, diff, style, color=color, lw=width)
                if reading == HEADLINE:
                    differences.fill_between(xs, low, high, color=color, alpha=0.15)
        differences.axhline(0.0, color="grey", lw=0.6)
        differences.set_ylim(-1.03, 1.03)
        differences.set_title(f"{case}: difference, same robots", fontsize=9)
    for axes in panels.flat:
        axes.grid(alpha=0.3)
        axes.tick_params(labelsize=8)
    for column in range(columns):
        panels[-1][column].set_xlabel("scale of the paper's disturbance", fontsize=8)
    for row in range(rows):
        panels[row][0].set_ylabel("survival", fontsize=8)
        panels[rows + row][0].set_ylabel("HuRi - PPO survival", fontsize=8)
    handles, labels = panels[0][0].get_legend_handles_labels()
    figure.legend(handles, labels, fontsize=7, loc="outside upper center", ncol=4)
    if found:  # the pairs by color, the readings by line style
        from matplotlib.lines import Line2D

        keys = [Line2D([], [], color=f"C{(len(shown) + k) % 10}", label=f"{a.entry.name} - {b.entry.name}")
                for k, (a, b) in enumerate(found)]  # fmt: skip
        keys += [Line2D([], [], color="black", ls=style, lw=1.0, label=reading.label)
                 for reading, style in ((HEADLINE, "-"), (PER_BODY, "--"), (SHORT_PUSH, ":"))]  # fmt: skip
        panels[rows][0].legend(handles=keys, fontsize=6, loc="lower left")
    save_figure(figure, path, FIGURE_DPI)
