"""``report``: an experiment folder's results as ``report.md`` and figures, beside the paper's numbers.

- the runs: steps, training and evaluation times, throughput;
- the Table-1 analog: survival per method x disturbance scenario, mean and 95% confidence interval across
  seeds (Student's t), with the paper's success rates;
- the training return (mean return of the last tenth of training) beside the paper's averages, and the
  Fig. 3 analog: return curves with 95% bands across seeds (``returns.png``);
- the Fig. 4 / Table 2 analog: velocity-tracking errors under load, friction, both, and on uneven ground;
- the Tables 8 and 9 analog: survival on the terrain tests (multi-terrain, stepping down platforms);
- the Fig. 5 analog: the critic's interquartile range and beta on the plane, under sudden pushes and on
  uneven ground, and ``risk.png``: value-distribution CDFs and beta traces along one episode;
- whether each of the paper's orderings holds in our means, and whether the confidence intervals
  separate the methods.

It reads whatever the folder holds, finished or not, and says which runs are missing. Standard tasks
(``Walker2d-v5``, ...) have their own report, ``grid.standard_report``.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from sb3_huri.experiments import paper
from sb3_huri.experiments.errors import ExperimentError
from sb3_huri.experiments.grid.layout import (
    EXPERIMENT_FILE,
    RunStatus,
    Settings,
    is_standard,
    load_settings,
    read_status,
    run_folder,
    shown_path,
)
from sb3_huri.experiments.markdown import mean_cell, table
from sb3_huri.experiments.statistics import mean_ci
from sb3_huri.runner.curve import final_return, read_curve
from sb3_huri.runner.evaluation import (
    PLANE_CASE,
    RISK_CASES,
    TABLE1_SCENARIOS,
    TERRAIN_SCENARIOS,
    TRACKING_SCENARIOS,
    read_trace,
)
from sb3_huri.runner.files import read_json, write_text
from sb3_huri.runner.record import PARTIAL, record_path, trace_path

REPORT_FILE = "report.md"
RETURNS_FIGURE = "returns.png"
RISK_FIGURE = "risk.png"
PUSH_CASE = "sudden-centroid"
RISK_LABELS = {PLANE_CASE: "plane", PUSH_CASE: "sudden push", "uneven": "uneven"}


@dataclass
class RunResult:
    """What a run folder holds: status, evaluation metrics per case, training curve, risk traces."""

    method: str
    seed: int
    folder: Path
    status: RunStatus
    cases: dict[str, dict[str, float]] = field(default_factory=dict)
    curve: list[dict[str, float]] = field(default_factory=list)
    traces: dict[str, dict[str, np.ndarray]] = field(default_factory=dict)

    @property
    def final_return(self) -> float:
        """Mean of SB3's ``ep_rew_mean`` over the last tenth of training (NaN without episodes)."""
        return final_return(self.curve)


def load_results(out: Path) -> tuple[Settings, list[RunResult]]:
    """The experiment's settings and every run of its grid (ExperimentError for a foreign or corrupt one)."""
    settings = load_settings(out)
    results = []
    for method, seed in settings.runs:
        folder = run_folder(out, settings.env, method, seed)
        result = RunResult(method, seed, folder, read_status(folder, method, seed, settings.env))
        steps = result.status.checkpoint
        record = record_path(folder, steps) if steps is not None else None
        record = record if record is None or record.exists() else record.with_name(record.name + PARTIAL)
        if record is not None and record.exists():
            evaluation = read_json(record, "a run's evaluation record")
            if not isinstance(evaluation, dict) or not isinstance(evaluation.get("cases"), dict):
                raise ExperimentError(f"{record} is corrupt; delete it to evaluate anew")
            result.cases = evaluation["cases"]
            for case in RISK_CASES:
                path = trace_path(folder, steps, case)
                if path.exists():
                    result.traces[case] = read_trace(path)
        result.curve = read_curve(folder)
        results.append(result)
    return settings, results


def _by_method(results: Sequence[RunResult]) -> dict[str, list[RunResult]]:
    grouped: dict[str, list[RunResult]] = {}
    for result in results:
        grouped.setdefault(result.method, []).append(result)
    return grouped


def _metric(runs: Sequence[RunResult], case: str, key: str) -> tuple[float, float, int]:
    return mean_ci([run.cases[case][key] for run in runs if case in run.cases and key in run.cases[case]])


def _label(method: str) -> str:
    return f"{paper.LABELS.get(method, method)} (`{method}`)"


def _ordering(
    order: Sequence[str], stats: dict[str, tuple[float, float, int]], larger_first: bool = True
) -> str:
    """Whether the means follow ``order`` (best first), and whether the 95% CIs separate each pair."""
    present = [key for key in order if stats.get(key, (math.nan, 0, 0))[2] > 0]
    if len(present) < 2:
        return "not testable (fewer than two of " + ", ".join(order) + " have results)"
    sign = 1 if larger_first else -1
    broken, overlapping = [], []
    no_ci = False
    for a, b in itertools.pairwise(present):
        (ma, ha, _), (mb, hb, _) = stats[a], stats[b]
        if not sign * (ma - mb) > 0:
            broken.append(f"{a} {ma:.3g} {'=' if ma == mb else 'vs'} {b} {mb:.3g}")
        elif not (math.isfinite(ha) and math.isfinite(hb)):
            no_ci = True
        elif abs(ma - mb) <= ha + hb:
            overlapping.append(f"{a}/{b}")
    chain = (" > " if larger_first else " < ").join(present)
    if broken:
        return f"**does not hold** ({chain}): " + "; ".join(broken)
    if no_ci:
        return f"holds in the means ({chain}); no confidence interval with one seed"
    if overlapping:
        return f"holds in the means ({chain}), within the 95% CIs for " + ", ".join(overlapping)
    return f"**holds** ({chain}), the 95% CIs separate every pair"


def write_report(out: str | Path) -> Path:
    """Write ``report.md``, ``returns.png`` and ``risk.png`` into the experiment folder ``out``; for a
    standard task, or a folder of standard tasks' experiment folders, ``grid.standard_report``'s report."""
    out = Path(out).resolve()
    if not (out / EXPERIMENT_FILE).is_file() or is_standard(load_settings(out).env):
        from sb3_huri.experiments.grid.standard_report import write_standard_report

        return write_standard_report(out)
    settings, results = load_results(out)
    grouped = _by_method(results)
    table1_lines, table1 = _table1_section(grouped)
    returns_lines, returns = _returns_section(grouped)
    tracking_lines, tracking = _tracking_section(grouped)
    terrain_lines = _terrain_section(grouped)
    risk_lines, iqr = _risk_section(grouped)
    lines = [
        *_header_section(out, settings, results),
        *_runs_section(results),
        *table1_lines,
        *returns_lines,
        *tracking_lines,
        *terrain_lines,
        *risk_lines,
        *_orderings_section(list(grouped), table1, returns, tracking, iqr),
    ]
    if any(r.cases for r in results) or any(r.curve for r in results):
        _plot_returns(out / RETURNS_FIGURE, grouped, settings.timesteps)
        _plot_risk(out / RISK_FIGURE, grouped)
    path = out / REPORT_FILE
    write_text(path, "\n".join(lines))
    return path


_Stats = dict[str, dict[str, tuple[float, float, int]]]
"""Per method, per case: mean, 95% half width and number of seeds."""


def _header_section(out: Path, settings: Settings, results: list[RunResult]) -> list[str]:
    methods = list(_by_method(results))
    lines = [
        f"# Experiment report: {settings.env}",
        "",
        f"Folder `{shown_path(out)}`: {len(results)} runs ({', '.join(methods)}; seeds "
        f"{', '.join(str(s) for s in sorted({r.seed for r in results}))}), {settings.timesteps} training "
        f"steps each, evaluated on {settings.eval.episodes} episodes of {settings.eval.episode_steps} steps "
        f"per case (seed {settings.eval.seed}). Means ± 95% confidence intervals across seeds (Student's t; "
        "none with one seed). Paper: HuRi paper, Table 1 (5 seeds x 10 runs).",
        "",
    ]
    missing = [f"{r.method} seed {r.seed} ({r.status.state})" for r in results if not r.cases]
    if missing:
        lines += [f"Not evaluated yet: {', '.join(missing)}.", ""]
    return lines


def _runs_section(results: list[RunResult]) -> list[str]:
    rows = []
    for r in results:
        s = r.status
        rate = f"{s.steps / s.train_seconds:.0f}" if s.train_seconds > 0 else "-"
        state = s.state + (f" (resumed from {', '.join(map(str, s.resumed_from))})" if s.resumed_from else "")
        times = [f"{s.train_seconds:.0f}", rate, f"{s.eval_seconds:.0f}"]
        rows.append([r.method, r.seed, s.steps, *times, state])
    header = ["method", "seed", "steps", "training s", "steps/s", "evaluation s", "state"]
    return ["## Runs", "", *table(header, rows)]


def _table1_section(grouped: dict[str, list[RunResult]]) -> tuple[list[str], _Stats]:
    """Survival under disturbances (Table 1 analog), and its statistics per method and case."""
    lines = [
        "",
        "## Survival under disturbances (Table 1 analog)",
        "",
        "Share of episodes without a fall; paper's success rate in parentheses. `plane`: walking at "
        f"{PLANE_CASE.split('@')[1]} m/s, no randomization, no force (not in the paper's table).",
        "",
    ]
    rows = []
    table1: _Stats = {}
    for method, runs in grouped.items():
        table1[method] = {case: _metric(runs, case, "survive") for case in TABLE1_SCENARIOS}
        per_seed = [
            np.mean([run.cases[c]["survive"] for c in TABLE1_SCENARIOS])
            for run in runs
            if all(c in run.cases for c in TABLE1_SCENARIOS)
        ]
        table1[method]["mean"] = mean_ci(per_seed)
        reference = paper.TABLE1.get(method)
        cells = []
        for case in TABLE1_SCENARIOS:
            ref = f" ({reference[case]:.3f})" if reference else ""
            cells.append(mean_cell(table1[method][case]) + ref)
        ref_mean = f" ({np.mean(list(reference.values())):.3f})" if reference else ""
        cells.append(mean_cell(table1[method]["mean"]) + ref_mean)
        cells.append(mean_cell(_metric(runs, PLANE_CASE, "survive")))
        rows.append([_label(method), *cells])
    return [*lines, *table(["method", *TABLE1_SCENARIOS, "mean", "plane"], rows)], table1


def _returns_section(
    grouped: dict[str, list[RunResult]],
) -> tuple[list[str], dict[str, tuple[float, float, int]]]:
    """Training return (Fig. 3 analog), and the mean return per method."""
    returns = {method: mean_ci([r.final_return for r in runs]) for method, runs in grouped.items()}
    lines = [
        "",
        "## Training return (Fig. 3 analog)",
        "",
        f"Mean episode return over the last tenth of training (SB3's `ep_rew_mean`, our reward scale); "
        f"the paper's average training return (its scale) beside it. Curves: ![returns]({RETURNS_FIGURE})",
        "",
    ]
    rows = []
    for method in grouped:
        ref = paper.TRAINING_RETURN.get(method)
        rows.append([_label(method), mean_cell(returns[method], 1), "-" if ref is None else f"{ref}"])
    return [*lines, *table(["method", "return", "paper"], rows)], returns


def _tracking_section(grouped: dict[str, list[RunResult]]) -> tuple[list[str], _Stats]:
    """Velocity tracking (Fig. 4 / Table 2 analog), and the linear velocity error per method and case."""
    lines = [
        "",
        "## Velocity tracking (Fig. 4 / Table 2 analog)",
        "",
        "Mean linear velocity error |v_xy - v_cmd| (m/s) / yaw-rate error |w_z - w_cmd| (rad/s) up to a "
        "fall, command 1 m/s, a random U[0, 100] N push every 0.5 s (not on uneven ground); survival in "
        "parentheses.",
        "",
    ]
    rows = []
    tracking: _Stats = {}
    for method, runs in grouped.items():
        tracking[method] = {case: _metric(runs, case, "lin_err") for case in TRACKING_SCENARIOS}
        cells = [
            f"{mean_cell(tracking[method][case])} / {mean_cell(_metric(runs, case, 'yaw_err'))} "
            f"({mean_cell(_metric(runs, case, 'survive'))})"
            for case in TRACKING_SCENARIOS
        ]
        rows.append([_label(method), *cells])
    return [*lines, *table(["method", *TRACKING_SCENARIOS], rows)], tracking


def _terrain_section(grouped: dict[str, list[RunResult]]) -> list[str]:
    """Survival on the paper's terrain tests (Tables 8 and 9 analog)."""
    lines = [
        "",
        "## Survival on terrains (Tables 8 and 9 analog)",
        "",
        "Share of episodes without a fall at 1 m/s: `multi-terrain` (Table 9: rough slopes up and down and "
        "discrete blocks, robots spread over the 10 levels, U[0, 100] N on the centroid), stepping down a "
        "0.40 / 0.45 m platform (Table 8: U[0, 100] N on the centroid every 2 s, +-1 kg). The paper trained "
        "on terrains for Table 9; these runs trained on their preset's scenario.",
        "",
    ]
    rows = []
    for method, runs in grouped.items():
        reference = paper.TERRAINS.get(method, {})
        cells = []
        for case in TERRAIN_SCENARIOS:
            ref = f" ({reference[case]:.3f})" if case in reference else ""
            cells.append(mean_cell(_metric(runs, case, "survive")) + ref)
        rows.append([_label(method), *cells])
    return [*lines, *table(["method", *TERRAIN_SCENARIOS], rows)]


def _risk_section(grouped: dict[str, list[RunResult]]) -> tuple[list[str], _Stats]:
    """Risk along the episodes (Fig. 5 analog), and the IQR per method and condition."""
    lines = [
        "",
        "## Risk along the episodes (Fig. 5 analog)",
        "",
        "The critic's interquartile range (IQR, normalized-return units) and risk parameter beta (Wang; "
        "CVaR methods: alpha; 0 for the scalar baseline critic), means over every robot-step. "
        f"Figure: ![risk]({RISK_FIGURE}) (top: CDF of the return quantiles, robot 0 of the first seed, "
        "averaged over its episode, under the push over the pushes' steps, or all of its steps if it fell "
        "before the first push; bottom: beta along that episode, the push's force in grey).",
        "",
    ]
    rows = []
    iqr: _Stats = {}
    for method, runs in grouped.items():
        iqr[method] = {RISK_LABELS[c]: _metric(runs, c, "iqr") for c in RISK_CASES}
        cells = [mean_cell(iqr[method][RISK_LABELS[c]], 3) for c in RISK_CASES]
        cells += [mean_cell(_metric(runs, c, "beta"), 3) for c in RISK_CASES]
        rows.append([_label(method), *cells])
    header = ["method", *(f"IQR {RISK_LABELS[c]}" for c in RISK_CASES)]
    return [*lines, *table([*header, *(f"beta {RISK_LABELS[c]}" for c in RISK_CASES)], rows)], iqr


def _orderings_section(
    methods: list[str],
    table1: _Stats,
    returns: dict[str, tuple[float, float, int]],
    tracking: _Stats,
    iqr: _Stats,
) -> list[str]:
    """Whether the paper's orderings of the methods hold in these results."""
    lines = ["", "## The paper's orderings in our results", ""]
    for case in (*TABLE1_SCENARIOS, "mean"):
        stats = {m: table1[m][case] for m in table1}
        lines.append(f"- Survival, {case} (Table 1): {_ordering(paper.RANKING, stats)}")
    lines.append(f"- Training return (Fig. 3): {_ordering(paper.RANKING, returns)}")
    for case in TRACKING_SCENARIOS:
        stats = {m: tracking[m][case] for m in tracking}
        lines.append(
            f"- Velocity error, {case} (our reading of Fig. 4: HuRi tracks better than the baseline): "
            f"{_ordering(('huri', 'huri-baseline'), stats, larger_first=False)}"
        )
    for method in ("huri", *[m for m in methods if m not in ("huri", "huri-baseline")]):
        if method in iqr:
            lines.append(
                f"- IQR {' > '.join(paper.RISK_ORDER)}, {method} (Fig. 5): "
                f"{_ordering(paper.RISK_ORDER, iqr[method])}"
            )
    lines.append("")
    return lines


def _plot_returns(path: Path, grouped: dict[str, list[RunResult]], timesteps: int) -> None:
    """Mean training return per method with a 95% band across seeds (Fig. 3 analog)."""
    from matplotlib.figure import Figure

    figure = Figure(figsize=(7, 4.2), layout="constrained")
    axes = figure.add_subplot()
    grid = np.linspace(0, timesteps, 100)
    for method, runs in grouped.items():
        curves = []
        for run in runs:
            rows = [r for r in run.curve if math.isfinite(r["ep_return"])]
            if len(rows) < 2:
                continue
            x = np.array([r["timesteps"] for r in rows])
            y = np.array([r["ep_return"] for r in rows])
            curves.append(np.where((grid >= x[0]) & (grid <= x[-1]), np.interp(grid, x, y), np.nan))
        if not curves:
            continue
        stats = [mean_ci(column) for column in np.array(curves).T]
        mean = np.array([s[0] for s in stats])
        half = np.nan_to_num(np.array([s[1] for s in stats]))
        seeds = f"{len(curves)} seed{'s' * (len(curves) > 1)}"
        (line,) = axes.plot(grid, mean, label=f"{paper.LABELS.get(method, method)} ({seeds})")
        axes.fill_between(grid, mean - half, mean + half, color=line.get_color(), alpha=0.2)
    axes.set_xlabel("environment steps")
    axes.set_ylabel("mean episode return (last 100 episodes)")
    axes.set_title("Training return, mean and 95% CI across seeds")
    axes.grid(alpha=0.3)
    if axes.lines:
        axes.legend(fontsize=8)
    figure.savefig(path, dpi=110)


def _mean_atoms(trace: dict[str, np.ndarray], case: str) -> np.ndarray | None:
    """The episode's return quantiles averaged over robot 0's steps (under the push: the pushed steps)."""
    atoms, force = trace["atoms"], trace["force"]
    alive = np.all(np.isfinite(atoms), axis=1)
    if case == PUSH_CASE and np.any(alive & (force > 100.0)):
        alive &= force > 100.0
    return atoms[alive].mean(axis=0) if alive.any() else None


def _plot_risk(path: Path, grouped: dict[str, list[RunResult]]) -> None:
    """Value-distribution CDFs (top) and beta traces (bottom) on the plane, under a push, uneven (Fig. 5)."""
    from matplotlib.figure import Figure

    from zerith_gym.zerith1.constants import CONTROL_DT

    figure = Figure(figsize=(12, 6.5), layout="constrained")
    panels = figure.subplots(2, len(RISK_CASES), squeeze=False)
    for column, case in enumerate(RISK_CASES):
        cdf_axes, beta_axes = panels[0][column], panels[1][column]
        force_drawn = False
        for method, runs in grouped.items():
            run = next((r for r in runs if case in r.traces), None)
            if run is None:
                continue
            trace: dict[str, Any] = run.traces[case]
            label = paper.LABELS.get(method, method)
            atoms = _mean_atoms(trace, case)
            if atoms is not None:  # the atoms' empirical CDF: a jump of 1/N at each (one jump: scalar critic)
                levels = np.arange(len(atoms) + 1) / len(atoms)
                cdf_axes.plot(np.repeat(np.sort(atoms), 2), np.repeat(levels, 2)[1:-1], label=label)
            time_s = np.arange(len(trace["beta"])) * CONTROL_DT
            beta_axes.plot(time_s, trace["beta"], label=label, linewidth=1)
            if case == PUSH_CASE and not force_drawn:  # the pushes are the same for every agent
                force_drawn = True
                force_axes = beta_axes.twinx()
                force_axes.fill_between(time_s, 0, np.nan_to_num(trace["force"]), color="grey", alpha=0.25)
                force_axes.set_ylabel("force (N)")
        cdf_axes.set_title(f"value distribution: {RISK_LABELS[case]}")
        cdf_axes.set_xlabel("return quantile (normalized)")
        cdf_axes.set_ylabel("CDF")
        beta_axes.set_title(f"beta: {RISK_LABELS[case]}")
        beta_axes.set_xlabel("time (s)")
        beta_axes.set_ylabel("beta")
        for axes in (cdf_axes, beta_axes):
            axes.grid(alpha=0.3)
    if panels[0][0].lines:
        panels[0][0].legend(fontsize=7)
    figure.savefig(path, dpi=100)
