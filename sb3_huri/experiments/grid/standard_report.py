"""``report`` for standard tasks (``grid.standard``): each task's final returns per method over seeds, and
the methods against PPO, in ``report.md``.

``report DIR`` on one task's experiment folder reports that task; on a folder of such folders (e.g.
``results/mujoco`` holding ``walker2d/`` and ``halfcheetah/``) it reports every task and, across them,
each method's probability of beating PPO averaged over the tasks. Per task and method:

- the final return, the mean over the run's evaluation episodes (``grid.standard``), as mean ± 95%
  confidence interval over seeds (Student's t) and each seed's value;
- the interquartile mean (IQM) over seeds, with a 95% percentile interval from a stratified bootstrap
  (seeds resampled within the task: ``statistics.stratified_bootstrap``);
- the probability that the method beats PPO (``huri-baseline``): P(X > Y) over every pair of a seed of the
  method and a seed of PPO, ties counting half, with its bootstrap interval (rliable's probability of
  improvement);
- each run's steps, training and evaluation time, training sessions and hardware (``state.json``).

It reads whatever the folders hold, finished or not, and names the runs not evaluated yet.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

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
from sb3_huri.experiments.grid.standard import RETURN_CASE
from sb3_huri.experiments.markdown import interval_cell, mean_cell, table
from sb3_huri.experiments.statistics import improvement_interval, iqm_interval, mean_ci
from sb3_huri.runner.files import read_json, write_text
from sb3_huri.runner.record import record_path
from sb3_huri.runner.state import RunState

REPORT_FILE = "report.md"
BASELINE = "huri-baseline"
"""The method every other is compared with: PPO with a scalar critic."""
RESAMPLES = 2000
"""Bootstrap resamples of every interval (seed 0: the same report from the same results)."""


@dataclass
class Run:
    """One run of a task: its status, its training state and its final return (NaN until evaluated)."""

    method: str
    seed: int
    status: RunStatus
    state: RunState
    final_return: float = math.nan


@dataclass
class Task:
    """One standard task's experiment folder: its settings and runs."""

    folder: Path
    settings: Settings
    runs: list[Run] = field(default_factory=list)

    def returns(self, method: str) -> list[float]:
        """The evaluated final returns of `method`, in seed order."""
        runs = sorted((r for r in self.runs if r.method == method), key=lambda r: r.seed)
        return [r.final_return for r in runs if math.isfinite(r.final_return)]

    @property
    def methods(self) -> list[str]:
        """The task's methods in the grid's order, PPO first."""
        methods = list(dict.fromkeys(r.method for r in self.runs))
        return sorted(methods, key=lambda method: method != BASELINE)


def load_task(out: Path) -> Task:
    """The standard task of the experiment folder `out` (ExperimentError for a Zerith one)."""
    settings = load_settings(out)
    if not is_standard(settings.env):
        raise ExperimentError(f"{out} is an experiment on {settings.env}, not on a standard task")
    task = Task(out, settings)
    for method, seed in settings.runs:
        folder = run_folder(out, settings.env, method, seed)
        status = read_status(folder, method, seed, settings.env)
        run = Run(method, seed, status, RunState.read(folder, settings.env))
        record = record_path(folder, status.checkpoint) if status.checkpoint is not None else None
        if record is not None and record.is_file():
            data = read_json(record, "a run's evaluation record")
            try:
                run.final_return = float(data["cases"][RETURN_CASE]["mean_return"])
            except (KeyError, TypeError, ValueError) as error:
                raise ExperimentError(
                    f"{record} is corrupt ({error!r}); delete it to evaluate anew"
                ) from error
        task.runs.append(run)
    return task


def standard_tasks(out: Path) -> list[Task]:
    """The tasks of `out`: itself if it is an experiment folder, else every experiment folder in it (at
    least one, each on a standard task)."""
    if (out / EXPERIMENT_FILE).is_file():
        return [load_task(out)]
    children = sorted(child for child in out.glob(f"*/{EXPERIMENT_FILE}"))
    if not out.is_dir() or not children:
        load_settings(out)  # raises the error that says what is missing
    return [load_task(child.parent) for child in children]


def write_standard_report(out: str | Path) -> Path:
    """Write ``report.md`` for the standard task(s) of `out` (see the module docstring); return its path."""
    out = Path(out).resolve()
    tasks = standard_tasks(out)
    lines = _header(out, tasks)
    for task in tasks:
        lines += _task_section(task)
    if len(tasks) > 1:
        lines += _across_section(tasks)
    for task in tasks:
        lines += _runs_section(task)
    path = out / REPORT_FILE
    write_text(path, "\n".join(lines) + "\n")
    return path


def _header(out: Path, tasks: list[Task]) -> list[str]:
    first = tasks[0].settings
    names = ", ".join(f"{t.settings.env} ({t.settings.timesteps:,} steps per run)" for t in tasks)
    lines = [
        f"# Standard tasks: {', '.join(t.settings.env for t in tasks)}",
        "",
        f"Folder `{shown_path(out)}`: {names}. Final return: the mean return of each run's final model over "
        f"{first.eval.episodes} deterministic episodes (seed {first.eval.seed}, the same for every run; the "
        "env's own time limit; the normalizer frozen, rewards unnormalized). Per method over seeds: mean ± "
        "95% confidence interval (Student's t); IQM (interquartile mean: the mean without the lowest and "
        "highest quarter of the seeds) with a 95% percentile interval from a bootstrap of the seeds, "
        f"stratified by task ({RESAMPLES} resamples); P(> PPO): the probability that a seed of the method "
        f"beats a seed of PPO (`{BASELINE}`), over every pair of seeds, ties counting half, with its "
        "bootstrap interval. Every run of the grid is reported, each trained with the preset its experiment "
        "began with (a folder refuses another).",
        "",
    ]
    for task in tasks:
        entries = sorted((k, v) for k, v in task.settings.preset.items() if k != "n_timesteps")  # the grid's
        preset = ", ".join(f"{key} {value}" for key, value in entries)
        lines += [f"{task.settings.env} preset: {preset}.", ""]
        missing = [
            f"{r.method} seed {r.seed} ({r.status.state})" for r in task.runs if math.isnan(r.final_return)
        ]
        if missing:
            lines += [f"{task.settings.env}, not evaluated yet: {', '.join(missing)}.", ""]
    return lines


def _task_section(task: Task) -> list[str]:
    """The task's table: per method, the mean with its t interval, the IQM, P(> PPO), each seed's value."""
    baseline = task.returns(BASELINE)
    rows = []
    for method in task.methods:
        values = task.returns(method)
        stat = mean_ci(values)
        iqm = interval_cell(*iqm_interval(values, resamples=RESAMPLES), ".1f") if values else "-"
        beats = (
            interval_cell(*improvement_interval([(values, baseline)], resamples=RESAMPLES))
            if values and baseline and method != BASELINE
            else "-"
        )
        seeds = sorted((r for r in task.runs if r.method == method), key=lambda r: r.seed)
        per_seed = ", ".join(
            f"{r.seed}: {r.final_return:.1f}" for r in seeds if math.isfinite(r.final_return)
        )
        rows.append([f"`{method}`", stat[2], mean_cell(stat, 1), iqm, beats, per_seed or "-"])
    header = ["method", "seeds", "mean ± 95% CI (t)", "IQM [95% CI]", "P(> PPO) [95% CI]", "per seed"]
    return ["", f"## {task.settings.env}", "", *table(header, rows)]


def _across_section(tasks: list[Task]) -> list[str]:
    """P(> PPO) averaged over the tasks, its bootstrap resampling each method's seeds within each task."""
    lines = [
        "",
        "## Across tasks",
        "",
        "P(> PPO) averaged over the tasks where both the method and PPO have evaluated seeds (rliable's "
        "aggregate probability of improvement), 95% stratified bootstrap interval.",
        "",
    ]
    rows = []
    for method in dict.fromkeys(m for task in tasks for m in task.methods if m != BASELINE):
        pairs = [(t.returns(method), t.returns(BASELINE)) for t in tasks]
        pairs = [(x, y) for x, y in pairs if x and y]
        cell = interval_cell(*improvement_interval(pairs, resamples=RESAMPLES)) if pairs else "-"
        rows.append([f"`{method}`", len(pairs), cell])
    return [*lines, *table(["method", "tasks", "P(> PPO) [95% CI]"], rows)]


def _hardware(state: RunState) -> str:
    names = list(dict.fromkeys(s.get("hardware", "unknown") for s in state.sessions))
    return "; ".join(names) or "-"


def _runs_section(task: Task) -> list[str]:
    """Each run of the task: steps, times, training sessions and the machines they ran on."""
    rows = []
    for run in task.runs:
        status = run.status
        wall = run.state.wall_s or status.train_seconds
        rate = f"{run.state.timesteps / wall:.0f}" if wall > 0 else "-"
        final = f"{run.final_return:.1f}" if math.isfinite(run.final_return) else "-"
        state = status.state + (
            f" (resumed from {', '.join(map(str, status.resumed_from))})" if status.resumed_from else ""
        )
        cells = [f"`{run.method}`", run.seed, run.state.timesteps, f"{wall:.0f}", rate]
        cells += [f"{status.eval_seconds:.1f}", len(run.state.sessions), _hardware(run.state), final, state]
        rows.append(cells)
    header = ["method", "seed", "steps", "training s", "steps/s", "evaluation s", "sessions", "hardware"]
    return ["", f"## Runs: {task.settings.env}", "", *table([*header, "final return", "state"], rows)]
