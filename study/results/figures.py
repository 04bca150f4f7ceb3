"""The results page's figures and their sections: robustness during training, training return (Fig. 3
analog), velocity tracking (Fig. 4 analog) and the critic's risk (Fig. 5 analog)."""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from sb3_huri.experiments import paper
from sb3_huri.experiments.markdown import table
from sb3_huri.runner.curve import final_return, read_curve
from sb3_huri.runner.evaluation import PLANE_CASE, RISK_CASES, read_trace
from sb3_huri.runner.record import trace_path
from sb3_huri.runner.robustness import read_rows
from study.campaign.queue import PROTOCOLS, CampaignEntry
from study.results.early_signal import early_signal_lines
from study.results.evaluations import (
    FIGURE_DPI,
    METHOD_COLORS,
    PROTOCOL_STYLES,
    PUSH_CASE,
    RISK_LABELS,
    TRACKING_CASES,
    Evaluated,
    method_label,
    runs_of,
    smoothed_curve,
    table1_mean,
)
from study.results.markdown import (
    figure_lines,
    link,
    save_figure,
    share_cell,
)
from study.results.sections import heading, section


def _run_label(run_entries: Sequence[CampaignEntry]) -> str:
    """A run's legend label: its entries, protocol, method and seed."""
    first = run_entries[0]
    names = ", ".join(entry.name for entry in run_entries)
    return f"{names} ({first.protocol}, {method_label(first.method)}, seed {first.seed})"


def _style(entry: CampaignEntry) -> dict[str, Any]:
    """Line color by method, line style by protocol."""
    color = METHOD_COLORS.get(entry.method)
    return {"linestyle": PROTOCOL_STYLES.get(entry.protocol, "-"), **({"color": color} if color else {})}


def robustness_section(
    entries: Sequence[CampaignEntry], evaluations: Sequence[Evaluated], figures: Path, out: Path
) -> list[str]:
    """The robustness section: every run's robustness learning curve, and its figure."""
    path = figures / "robustness.png"
    lines = [
        heading("robustness", "Robustness during training"),
        "",
        "`robustness.csv` of each run: the Table-1 mean of a checkpoint every ~5M steps, on fewer robots "
        "than the final evaluation and other seeds (the numbers in each row), so the curve is a trend, "
        f"noisier than {section('table1')}; stars: the final evaluations' Table-1 means. Color: method; "
        "line style: "
        "protocol (robust solid, paper dashed, terrain dotted).",
        "",
    ]
    curves, table_rows = {}, []
    for run, run_entries in runs_of(entries).items():
        rows = list(read_rows(run).values())
        if not rows:
            continue
        curves[run] = rows
        last = rows[-1]
        names, steps = ", ".join(e.name for e in run_entries), f"{int(last['timesteps']):,}"
        mean = f"{float(last['table1_mean']):.3f}"
        table_rows.append([f"`{link(run, out)}`", names, len(rows), steps, mean, last["episodes"]])
    if not curves:
        return [*lines, "No run has a robustness curve yet.", "", *figure_lines(path, out, drawn=False)]
    _plot_robustness(path, runs_of(entries), curves, evaluations)
    header = ["run", "entries", "rows", "newest row: steps", "its Table-1 mean", "robots per case"]
    lines += [*table(header, table_rows), "", *figure_lines(path, out)]
    return [*lines, *early_signal_lines(entries, out)]


def _plot_robustness(
    path: Path,
    runs: dict[Path, list[CampaignEntry]],
    curves: dict[Path, list[dict[str, str]]],
    evaluations: Sequence[Evaluated],
) -> None:
    """Every run's Table-1 mean by steps, one line per run, its final evaluations as stars."""
    from matplotlib.figure import Figure

    figure = Figure(figsize=(8, 4.6), layout="constrained")
    axes = figure.add_subplot()
    for run, rows in curves.items():
        steps = np.array([int(row["timesteps"]) for row in rows]) / 1e6
        (line,) = axes.plot(
            steps,
            [float(row["table1_mean"]) for row in rows],
            lw=1.5,
            label=_run_label(runs[run]),
            **_style(runs[run][0]),
        )
        own = [e for e in evaluations if e.entry.run == run]
        axes.plot(
            [e.steps / 1e6 for e in own],
            [table1_mean(e)[0] for e in own],
            "*",
            ms=11,
            color=line.get_color(),
            markeredgecolor="black",
        )
    axes.set_xlabel("environment steps (millions)")
    axes.set_ylabel("Table-1 mean survival")
    axes.set_ylim(-0.02, 1.02)
    axes.grid(alpha=0.3)
    axes.set_title("Robustness during training (stars: final evaluations)")
    figure.legend(fontsize=7, loc="outside lower center", ncol=2)
    save_figure(figure, path, FIGURE_DPI)


def returns_section(entries: Sequence[CampaignEntry], figures: Path, out: Path) -> list[str]:
    """The return section: the training return of every run, and the Fig. 3 analog."""
    path = figures / "returns.png"
    lines = [
        heading("returns", "Training return (Fig. 3 analog)"),
        "",
        "Mean training episode return (SB3's `ep_rew_mean`, our reward scale, which differs from the "
        "paper's) against samples, a moving average over 50 rollouts; one line per method and protocol, the "
        "mean over seeds where there are several, with a min-max band over the seeds (not a confidence "
        "band: with two or three seeds a 95% band would say little).",
        "",
    ]
    rows = []
    groups: dict[tuple[str, str], list[tuple[np.ndarray, np.ndarray]]] = {}
    for run, run_entries in runs_of(entries).items():
        curve = read_curve(run)
        if not curve:
            continue
        entry = run_entries[0]
        steps, returns = smoothed_curve(run)
        if steps.size:  # no episode ended yet: no return to draw
            groups.setdefault((entry.protocol, entry.method), []).append((steps, returns))
        reference = paper.TRAINING_RETURN.get(entry.method)
        names, trained = ", ".join(e.name for e in run_entries), f"{int(curve[-1]['timesteps']):,}"
        rows.append([f"`{link(run, out)}`", names, trained, f"{final_return(curve):.1f}", reference or "-"])
    if not groups:
        return [*lines, "No run has a learning curve yet.", "", *figure_lines(path, out, drawn=False)]
    _plot_returns(path, groups)
    header = ["run", "entries", "steps", "return, last tenth of its steps"]
    lines += [*table([*header, "paper's average return (its scale)"], rows), ""]
    return [*lines, *_curriculum_sentences(entries, out), *figure_lines(path, out)]


def _curriculum_sentences(entries: Sequence[CampaignEntry], out: Path) -> list[str]:
    """Where a run's randomization curriculum (``curve.csv``'s ``scale``) grew: its return then measures a
    task that gets harder, and falls for that reason too."""
    lines = []
    for run in runs_of(entries):
        scales = [(row["timesteps"], row["scale"]) for row in read_curve(run) if math.isfinite(row["scale"])]
        if not scales or scales[0][1] >= 1.0:
            continue
        full = next((steps for steps, scale in scales if scale >= 1.0), None)
        where = f"reached full scale at {int(full):,} steps" if full else f"is at {scales[-1][1]:.2f} so far"
        lines.append(
            f"- `{link(run, out)}`: its curriculum started the randomization and forces at scale "
            f"{scales[0][1]:.2f} and {where}; the return falls as the task grows harder, and compares "
            "across runs only at the same scale."
        )
    return [*lines, ""] if lines else []


def _plot_returns(path: Path, groups: dict[tuple[str, str], list[tuple[np.ndarray, np.ndarray]]]) -> None:
    """One panel per protocol: per method the mean smoothed return over its seeds, a min-max band where
    there are several (each seed counted up to where its run stopped)."""
    from matplotlib.figure import Figure

    protocols = [p for p in PROTOCOLS if any(key[0] == p for key in groups)]
    figure = Figure(figsize=(5 * len(protocols) + 1, 4), layout="constrained")
    panels = figure.subplots(1, len(protocols), squeeze=False, sharey=True)[0]
    for axes, protocol in zip(panels, protocols, strict=True):
        for (own, method), curves in groups.items():
            if own != protocol:
                continue
            grid = np.linspace(0, max(steps[-1] for steps, _ in curves), 400)
            values = np.array([np.where(grid <= s[-1], np.interp(grid, s, r), np.nan) for s, r in curves])
            masked = np.ma.masked_invalid(values)  # a seed's curve ends where its run stopped
            color = METHOD_COLORS.get(method)
            label = f"{method_label(method)} ({len(curves)} seed{'s' * (len(curves) > 1)})"
            mean = masked.mean(axis=0).filled(np.nan)
            (line,) = axes.plot(grid / 1e6, mean, lw=1.5, label=label, **({"color": color} if color else {}))
            if len(curves) > 1:
                several = masked.count(axis=0) > 1
                low, high = (
                    np.where(several, bound.filled(np.nan), np.nan)
                    for bound in (masked.min(axis=0), masked.max(axis=0))
                )
                axes.fill_between(grid / 1e6, low, high, color=line.get_color(), alpha=0.2)
        axes.set_title(f"{protocol} protocol")
        axes.set_xlabel("environment steps (millions)")
        axes.grid(alpha=0.3)
        axes.legend(fontsize=8)
    panels[0].set_ylabel("training return (moving average)")
    save_figure(figure, path, FIGURE_DPI)


def tracking_section(evaluations: Sequence[Evaluated], figures: Path, out: Path) -> list[str]:
    """The tracking section: velocity-tracking errors and survival under load, friction and both (Fig. 4
    analog)."""
    path = figures / "tracking.png"
    lines = [
        heading("tracking", "Velocity tracking (Fig. 4 analog)"),
        "",
        "Mean linear velocity error |v_xy - v_cmd| (m/s) and yaw-rate error |w_z - w_cmd| (rad/s) over the "
        "steps before a fall, command 1 m/s, a random U[0, 100] N push every 0.5 s; survival (Wilson 95%) "
        "beside them. An agent that falls early is measured on fewer, earlier steps: compare the errors of "
        "agents whose survival is alike.",
        "",
    ]
    shown = [e for e in evaluations if any(case in e.data["cases"] for case in TRACKING_CASES)]
    rows = []
    for evaluated in shown:
        cells = [evaluated.label]
        for case in TRACKING_CASES:
            outcomes = evaluated.survived(case)
            survival = "-" if outcomes is None else share_cell(float(outcomes.mean()), outcomes.size)
            errors = f"{evaluated.metric(case, 'lin_err'):.3f} / {evaluated.metric(case, 'yaw_err'):.3f}"
            cells.append(f"{errors} ({survival})")
        rows.append(cells)
    if not shown:
        return [*lines, "No entry is evaluated yet.", "", *figure_lines(path, out, drawn=False)]
    _plot_tracking(path, shown)
    header = ["agent", *(f"{case}: linear / yaw (survival)" for case in TRACKING_CASES)]
    return [*lines, *table(header, rows), "", *figure_lines(path, out)]


def _plot_tracking(path: Path, shown: Sequence[Evaluated]) -> None:
    """Bars of the linear (top) and yaw-rate (bottom) errors per case and agent, labelled with survival."""
    from matplotlib.figure import Figure

    figure = Figure(figsize=(8, 5.2), layout="constrained")
    panels = figure.subplots(2, 1, sharex=True)
    width = 0.8 / len(shown)
    x = np.arange(len(TRACKING_CASES))
    for axes, key, unit in zip(panels, ("lin_err", "yaw_err"), ("m/s", "rad/s"), strict=True):
        for index, evaluated in enumerate(shown):
            values = [evaluated.metric(case, key) for case in TRACKING_CASES]
            bars = axes.bar(x + (index - (len(shown) - 1) / 2) * width, values, width, label=evaluated.label)
            survival = [evaluated.metric(case, "survive") for case in TRACKING_CASES]
            axes.bar_label(bars, [f"{s:.2f}" for s in survival], fontsize=7, padding=1)
        axes.set_ylabel(f"{'linear' if key == 'lin_err' else 'yaw-rate'} error ({unit})")
        axes.grid(alpha=0.3, axis="y")
        axes.margins(y=0.15)
    panels[1].set_xticks(x, TRACKING_CASES)
    panels[0].set_title("Velocity tracking error (bar labels: survival)")
    panels[0].legend(fontsize=7)
    save_figure(figure, path, FIGURE_DPI)


def _risk_order(evaluated: Evaluated) -> str:
    """Whether the agent's mean IQR follows the paper's order, uneven > push > plane (Fig. 5)."""
    iqr = [evaluated.metric(case, "iqr") for case in ("uneven", PUSH_CASE, PLANE_CASE)]
    if not all(math.isfinite(value) for value in iqr):
        return "not traced"
    if max(iqr) == 0.0:
        return "IQR 0 everywhere (a scalar critic: one atom)"
    holds = iqr[0] > iqr[1] > iqr[2]
    return ("holds" if holds else "does not hold") + " (uneven > push > plane)"


def risk_section(evaluations: Sequence[Evaluated], figures: Path, out: Path) -> list[str]:
    """The risk section: the critic's IQR and beta per agent and condition, and robot 0's traces (Fig. 5
    analog)."""
    path = figures / "risk.png"
    lines = [
        heading("risk", "Risk along the episodes (Fig. 5 analog)"),
        "",
        "The critic's interquartile range (IQR, in normalized-return units) and risk parameter beta (Wang; "
        "positive is risk-averse), means over every robot-step, on the plane (`nominal@1`), under sudden "
        "150-200 N pushes on the centroid (`sudden-centroid`) and on uneven ground. The PPO baseline's "
        "critic is scalar: its IQR and beta are 0 by construction. Figure: robot 0's critic value (the "
        "mean of its quantiles; the trace ends where the robot fell), IQR and beta along its episode, the "
        "pushes' force in grey. The value's units are each checkpoint's own reward normalization: compare "
        "its shape along the episode, not its level across agents.",
        "",
    ]
    traced = [
        e for e in evaluations if any(trace_path(e.entry.run, e.steps, c).is_file() for c in RISK_CASES)
    ]
    if not traced:
        return [*lines, "No risk trace is written yet.", "", *figure_lines(path, out, drawn=False)]
    rows = []
    for evaluated in evaluations:
        cells = [f"{evaluated.metric(case, key):.3f}" for key in ("iqr", "beta") for case in RISK_CASES]
        rows.append([evaluated.label, *cells, _risk_order(evaluated)])
    _plot_risk(path, traced)
    header = ["agent", *(f"{key} {RISK_LABELS[c]}" for key in ("IQR", "beta") for c in RISK_CASES)]
    return [*lines, *table([*header, "paper's IQR order"], rows), "", *figure_lines(path, out)]


RISK_ROWS = (
    ("value", "critic value (normalized return)"),
    ("iqr", "IQR (normalized return)"),
    ("beta", "beta"),
)
"""The rows of the risk figure: the critic's value (mean of its quantiles: a scalar critic's one atom), its
interquartile range and the risk parameter, along robot 0's episode."""


def _plot_risk(path: Path, traced: Sequence[Evaluated]) -> None:
    """Robot 0's critic value, IQR and beta along its episode per risk case (columns), the pushes' force in
    grey under the push's value."""
    from matplotlib.figure import Figure

    from zerith_gym.zerith1.constants import CONTROL_DT

    figure = Figure(figsize=(12, 7.5), layout="constrained")
    panels = figure.subplots(len(RISK_ROWS), len(RISK_CASES), squeeze=False, sharex=True)
    for column, case in enumerate(RISK_CASES):
        files = [(e, trace_path(e.entry.run, e.steps, case)) for e in traced]
        traces = [(e, read_trace(file)) for e, file in files if file.is_file()]
        for evaluated, trace in traces:
            time_s = np.arange(len(trace["beta"])) * CONTROL_DT
            series = {"value": trace["atoms"].mean(axis=1), "iqr": trace["iqr"], "beta": trace["beta"]}
            for row, (key, _) in enumerate(RISK_ROWS):
                panels[row][column].plot(time_s, series[key], lw=1, label=evaluated.label)
        if case == PUSH_CASE and traces:  # the same robots, so the same pushes, for every agent
            force = np.nan_to_num(traces[0][1]["force"])
            force_axes = panels[0][column].twinx()
            force_axes.fill_between(np.arange(len(force)) * CONTROL_DT, 0, force, color="grey", alpha=0.25)
            force_axes.set_ylabel("force (N)")
            force_axes.set_zorder(panels[0][column].get_zorder() - 1)  # the force behind the value
            panels[0][column].patch.set_visible(False)
        for row, (key, _) in enumerate(RISK_ROWS):
            panels[row][column].set_title(f"{key}: {RISK_LABELS[case]}")
            panels[row][column].grid(alpha=0.3)
        panels[-1][column].set_xlabel("time (s)")
    for row, (_, label) in enumerate(RISK_ROWS):
        panels[row][0].set_ylabel(label)
    panels[0][0].legend(fontsize=7)
    save_figure(figure, path, FIGURE_DPI)
