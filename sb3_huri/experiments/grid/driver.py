"""``run``: check the grid, open the experiment folder, skip finished runs, hand the others to a backend
and print one status line per run as it trains, evaluates and finishes."""

from __future__ import annotations

import time
from collections import deque
from collections.abc import Callable, Iterable, Sequence
from pathlib import Path

from sb3_huri.experiments.errors import ExperimentError
from sb3_huri.experiments.grid.backends import Backend, LocalBackend, RayBackend
from sb3_huri.experiments.grid.job import RunJob, RunOutcome, is_finished
from sb3_huri.experiments.grid.layout import (
    EvalSettings,
    Settings,
    open_experiment,
    read_status,
    run_folder,
    validate_grid,
)
from sb3_huri.runner.files import RunError
from sb3_huri.runner.state import RunState
from zerith_gym.cpu.workers import available_cores

EXECUTION_BACKENDS = ("local", "ray")


def _settings(
    env: str,
    grid: list[tuple[str, int]],
    timesteps: int,
    eval_settings: EvalSettings | None,
    checkpoint_freq: int,
    conf: str | Path | None,
) -> Settings:
    """The experiment's settings, checked (ExperimentError), with the env's preset from ``conf``."""
    from sb3_huri.zoo import read_preset

    for name, value in (("timesteps", timesteps), ("checkpoint_freq", checkpoint_freq)):
        if value < 1:
            raise ExperimentError(f"{name} must be positive, got {value}")
    eval_settings = eval_settings or EvalSettings()
    if eval_settings.episodes < 1 or eval_settings.episode_steps < 1:
        raise ExperimentError(f"evaluation needs at least one episode of one step, got {eval_settings}")
    try:
        preset = read_preset(env, conf)
    except (OSError, ValueError) as error:
        raise ExperimentError(str(error)) from error
    return Settings(env, preset, int(timesteps), eval_settings, int(checkpoint_freq), grid)


def run_experiment(
    out: str | Path,
    env: str,
    methods: Sequence[str],
    seeds: Sequence[int],
    timesteps: int,
    eval_settings: EvalSettings | None = None,
    *,
    backend: str = "local",
    parallel: int | None = None,
    cpus_per_run: int | None = None,
    conf: str | Path | None = None,
    checkpoint_freq: int = 50_000,
    ray_address: str | None = None,
    poll_seconds: float = 5.0,
    echo: Callable[[str], None] = print,
) -> list[RunOutcome]:
    """Train and evaluate every (method, seed) of the grid in ``out``; return the outcome of each run.

    Finished runs are skipped, unfinished ones continue from their last checkpoint. ``parallel``: runs at
    once (local default: one per core, at most the runs left; Ray default: every run, Ray queues them
    by the CPUs free); ``cpus_per_run``: cores of each run (local default: the machine's cores shared
    among the parallel runs; Ray default: 1). ``conf``: the RL Zoo hyperparameter file holding the env's
    preset (default: the packaged ``huri.yml``). ExperimentError for a bad grid or output folder.
    """
    if backend not in EXECUTION_BACKENDS:
        raise ExperimentError(f"unknown backend {backend!r}; backends: {', '.join(EXECUTION_BACKENDS)}")
    grid = validate_grid(env, methods, seeds)
    out = Path(out).resolve()
    settings = open_experiment(out, _settings(env, grid, timesteps, eval_settings, checkpoint_freq, conf))

    outcomes, todo = [], []
    for method, seed in grid:
        if is_finished(out, method, seed):
            outcomes.append(RunOutcome(method, seed, "done", "finished earlier"))
        else:
            todo.append((method, seed))
    echo(
        f"{out}: {len(grid)} run(s) of {settings.timesteps} steps on {env} "
        f"({len(grid) - len(todo)} finished earlier, {len(todo)} to train or evaluate)"
    )
    if not todo:
        return outcomes

    cores = available_cores()
    if backend == "local":
        parallel = parallel or min(len(todo), cores)
        cpus = cpus_per_run or max(1, cores // parallel)
        runner: Backend = LocalBackend(parallel)
        echo(f"local backend: {parallel} run(s) at once, {cpus} core(s) each")
        if parallel * cpus > cores:
            echo(f"warning: {parallel * cpus} cores asked for on {cores}: runs share cores and train slower")
    else:
        cpus = cpus_per_run or 1
        runner = RayBackend(cpus, ray_address)
        parallel = parallel or len(todo)
        echo(f"ray backend: {cpus} CPU(s) per run, up to {parallel} runs at once")
    tasks = deque(RunJob(str(out), method, seed, cpus) for method, seed in todo)
    progress = _Progress(out, settings, echo)
    running: dict[object, RunJob] = {}
    try:
        while tasks or running:
            while tasks and len(running) < parallel:
                task = tasks.popleft()
                running[runner.submit(task)] = task
            for handle in runner.wait(running, poll_seconds):
                task = running.pop(handle)
                try:
                    outcome = runner.result(handle)
                except Exception as error:  # the job's process died (a kill, out of memory) or Ray gave up
                    outcome = RunOutcome(task.method, task.seed, "failed", f"{type(error).__name__}: {error}")
                outcomes.append(outcome)
                progress.finished(outcome, done=sum(o.state == "done" for o in outcomes), total=len(grid))
            progress.poll(running.values())
    except KeyboardInterrupt:
        echo("interrupted: the unfinished runs keep their last checkpoints; the same command continues them")
        runner.stop(list(running))
        raise
    runner.close()
    return outcomes


class _Progress:
    """One line per run when it starts a phase, passes another tenth of its steps, or finishes."""

    def __init__(self, out: Path, settings: Settings, echo: Callable[[str], None]) -> None:
        self.out, self.settings, self.echo = out, settings, echo
        self.shown: dict[tuple[str, int], tuple[str, int]] = {}
        self.first: dict[tuple[str, int], tuple[int, float]] = {}

    def poll(self, tasks: Iterable[RunJob]) -> None:
        for task in tasks:
            key = (task.method, task.seed)
            try:
                folder = run_folder(self.out, self.settings.env, task.method, task.seed)
                status = read_status(folder, task.method, task.seed, self.settings.env)
            except RunError:
                continue
            total = self.settings.timesteps
            now = time.time()
            if status.state == "training":
                status.steps = max(
                    status.steps, RunState.read(folder, self.settings.env).timesteps
                )  # the newest checkpoint
                steps0, t0 = self.first.setdefault(key, (status.steps, now))
                mark = ("training", min(10, 10 * status.steps // total))
                rate = (status.steps - steps0) / (now - t0) if now > t0 else 0.0
                line = (
                    f"training {status.steps}/{total} steps ({100 * status.steps // total}%)"
                    + (f", {rate:.0f} steps/s" if rate > 0 else "")
                    + (f", resumed from {status.resumed_from[-1]}" if status.resumed_from else "")
                )
            elif status.state == "evaluating":
                mark = ("evaluating", status.eval_done)
                line = f"evaluating: {status.eval_done}/{status.eval_cases} cases"
            else:
                continue
            if self.shown.get(key) != mark:
                self.shown[key] = mark
                self.echo(f"{task.method} seed {task.seed}: {line}")

    def finished(self, outcome: RunOutcome, done: int, total: int) -> None:
        head = f"{outcome.method} seed {outcome.seed}"
        if outcome.state == "done":
            self.echo(
                f"{head}: done, {outcome.steps} steps, trained in {outcome.train_seconds:.0f} s, "
                f"evaluated in {outcome.eval_seconds:.0f} s ({done}/{total} runs done)"
            )
        elif outcome.state == "busy":
            self.echo(f"{head}: skipped, {outcome.message}")
        else:
            last = outcome.message.strip().splitlines()[-1] if outcome.message.strip() else "unknown error"
            folder = run_folder(self.out, self.settings.env, outcome.method, outcome.seed)
            self.echo(f"{head}: FAILED: {last} (details in {folder}/status.json)")
