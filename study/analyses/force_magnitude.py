"""Survival over the force's magnitude: each Table-1 case and Fig. 4's load, friction and load-friction cases
at a range of scales of the paper's disturbance, for every evaluated Zerith-1 agent of the campaign.

**Scales.** A case at scale s is the paper's case with its disturbance multiplied by s:

- Table 1 (``continuous-*``, ``sudden-*``): the force's magnitude range times s (U[0, 100 s] N redrawn every
  0.1 s; U[150 s, 200 s] N every 2 s); the robot's test ranges (Table 5: load, friction, CoM offset) stay;
- Fig. 4 (``load``, ``friction``, ``load-friction``): the force (U[0, 100] N held 0.5 s) times s, and the
  robot's perturbation with it: the added mass's range times s ([-3 s, 8 s] kg) and the friction's bounds
  raised to the power s ([0.1^s, 2^s]: the factor from the nominal 1 scaled on a log scale, which stays
  positive; scaled linearly, the lower bound would reach 0 at 1.11x).

**Readings.** A ``Reading`` says how the disturbance is read where the paper leaves it open: ``per_body``:
one force vector drawn for both hands (feet) and acting on each, the env's default and the reading of the
campaign's evaluations, or each hand (foot) drawing its own (``ForceSchedule.per_body``); ``hold_steps``: a
sudden push lasting 5 control steps (0.1 s, the env's default) or 1 (0.02 s); ``robot``: Table 5's test
ranges (as Table 1) or the nominal robot (no randomization, Table-1 cases only). The headline reading is the
env's default: test ranges, one vector per pair, 0.1-s pushes. A reading changes only the cases it concerns
(the hands and feet cases, the sudden ones, the Table-1 ones): the others are measured once and shared,
stored under the reading that names only what changes them (``Reading.canonical``).

**Robots.** Robot i is seeded ``seed + i`` in every case, scale and reading: every agent meets the same robots
(the same domain draws at every scale; the same forces in a case, scale and reading; per body, the first
hand or foot gets the force it gets under one vector per pair), so two agents' outcomes pair robot by robot;
the default seed, 2000, makes them the first robots of the campaign's final evaluations. Each robot runs one
20-s episode at 1 m/s with the deterministic policy (``sb3_huri.runner.evaluation.evaluate``).

**Results.** ``<run>/evaluations/<steps>-force_magnitude.json``: per canonical reading, case and scale each
robot's fall step (null: no fall), written (atomically) after each case and scale; a later call with the same
settings skips what is done. The file holds no ``entry`` key, the key by which the campaign tells its final
evaluations (``<steps>.json``) apart. The model is the run's at the evaluated step: its newest model or a
kept checkpoint if it is at that step, else the model and statistics committed with the run's state at that
step (git history), else the saved model nearest to it, the file then named by the steps measured and
recording the steps evaluated.

From the files: ``survival_curve`` (survival per scale), ``half_survival_scale`` (the scale at which survival
first falls to 50%, interpolated linearly between the two scales around it), ``paired_curve`` (two agents'
difference on the same robots at each scale, Newcombe's paired 95% interval) and ``table1_difference`` (the
Table-1 mean's per-robot difference, a Student-t interval over the robots). ``study.scripts.force_magnitude``
is the command line; the results page's force-magnitude section shows the files.
"""

from __future__ import annotations

import contextlib
import json
import math
import shutil
import subprocess
import tempfile
import time
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from sb3_huri.experiments.errors import ExperimentError
from sb3_huri.experiments.statistics import mean_ci, paired_difference_interval
from sb3_huri.runner.evaluation import TABLE1_SCENARIOS, evaluate
from sb3_huri.runner.files import read_json, resumed_record, write_json
from sb3_huri.runner.record import EVALUATIONS
from zerith_gym import ZERITH1_ID
from zerith_gym.core.disturbances import ForceSchedule
from zerith_gym.core.randomization import NOMINAL, RandomizationRanges
from zerith_gym.core.scenarios import SCENARIOS, Scenario
from zerith_gym.zerith1.constants import CONTROL_DT

FIG4_CASES = ("load", "friction", "load-friction")
"""The paper's Fig. 4 conditions: a load, a friction, both, under U[0, 100] N on the centroid every 0.5 s."""
CASES = (*TABLE1_SCENARIOS, *FIG4_CASES)
SCALES = (0.1, 0.25, 0.4, 0.55, 0.7, 0.85, 1.0, 1.25, 1.5)
"""The scales measured by default: 0.15 apart up to the paper's 1x, 0.25 beyond."""
PAPER_SCALE = 1.0
DEFAULT_ROBOTS = 32
DEFAULT_SEED = 2000
"""The first robots of the campaign's final evaluation (``eval_seed``)."""
SUFFIX = "-force_magnitude.json"
"""A checkpoint's measurements are in its run's ``evaluations/``, in ``<steps>-force_magnitude.json``."""
ROBOTS = ("test", "nominal")
PUSH_HOLDS = (5, 1)
"""A sudden push's hold times in control steps: 0.1 s (the env's) and one control step (0.02 s)."""


@dataclass(frozen=True)
class Reading:
    """How a case's disturbance is read (see the module docstring)."""

    robot: str = "test"
    per_body: bool = False
    hold_steps: int = 5

    def __post_init__(self) -> None:
        if self.robot not in ROBOTS:
            raise ValueError(f"a reading's robot is one of {', '.join(ROBOTS)}, got {self.robot!r}")
        if not isinstance(self.hold_steps, int) or self.hold_steps < 1:
            raise ValueError(f"a push's hold time is a positive number of steps, got {self.hold_steps!r}")

    @property
    def key(self) -> str:
        """``robot:pair|per-body:holdN``, the reading's name in the files and on the command line."""
        return f"{self.robot}:{'per-body' if self.per_body else 'pair'}:hold{self.hold_steps}"

    @staticmethod
    def parse(key: str) -> Reading:
        """The reading named ``key``; ValueError if it names none."""
        parts = key.split(":")
        if len(parts) != 3 or parts[1] not in ("pair", "per-body") or not parts[2].startswith("hold"):
            raise ValueError(
                f"a reading is robot:pair|per-body:holdN (e.g. test:per-body:hold5), got {key!r}"
            )
        hold = parts[2][len("hold") :]
        if not hold.isdigit():
            raise ValueError(f"a reading's hold time is a number of control steps, got {key!r}")
        return Reading(parts[0], parts[1] == "per-body", int(hold))

    @property
    def label(self) -> str:
        """The reading in words."""
        bodies = "a force per hand / foot" if self.per_body else "one force per pair of hands / feet"
        hold = f"{self.hold_steps * CONTROL_DT:.2g}-s pushes"
        return f"{bodies}, {hold}" + (", nominal robot" if self.robot == "nominal" else "")

    def canonical(self, case: str) -> Reading:
        """The reading ``case`` is measured and stored under: this one, less what does not concern the case
        (the bodies outside the hands and feet cases, the hold time outside the sudden ones, the robot
        outside Table 1)."""
        schedule = _schedule(case)
        return Reading(
            self.robot if case in TABLE1_SCENARIOS else "test",
            self.per_body and schedule.target in ("hands", "feet"),
            self.hold_steps if _is_push(schedule) else 5,
        )


HEADLINE = Reading()
"""The env's default reading: the campaign's evaluations', the results page's headline."""
READINGS = tuple(Reading("test", per_body, hold) for per_body in (False, True) for hold in PUSH_HOLDS)
"""Both readings of the forces on the hands and feet, with both hold times of a push."""
NOMINAL_READINGS = (Reading("nominal"), Reading("nominal", per_body=True))


def _schedule(case: str) -> ForceSchedule:
    if case not in CASES:
        raise ValueError(f"unknown case {case!r}: one of {', '.join(CASES)}")
    schedule = SCENARIOS[case].force
    assert isinstance(schedule, ForceSchedule)
    return schedule


def _is_push(schedule: ForceSchedule) -> bool:
    """Whether the schedule strikes impulses (a force held shorter than its period)."""
    return schedule.duration_steps < schedule.period_steps


def scaled_robot(ranges: RandomizationRanges, scale: float) -> RandomizationRanges:
    """Fig. 4's perturbation of the robot at ``scale``: the added mass's range times ``scale`` (about the
    nominal 0), the friction's bounds' factor from the nominal raised to the power ``scale``."""
    mass = tuple(n + scale * (v - n) for v, n in zip(ranges.added_mass, NOMINAL.added_mass, strict=True))
    friction = tuple(n * (v / n) ** scale for v, n in zip(ranges.friction, NOMINAL.friction, strict=True))
    return replace(ranges, added_mass=mass, friction=friction)


def stressed(case: str, scale: float, reading: Reading = HEADLINE) -> Scenario:
    """``case``'s scenario with its disturbance at ``scale`` under ``reading`` (the module docstring)."""
    if not scale > 0:
        raise ValueError(f"a scale is positive, got {scale!r}")
    scenario, schedule = SCENARIOS[case], _schedule(case)
    reading = reading.canonical(case)
    force = replace(schedule.scaled(scale), per_body=reading.per_body)
    if _is_push(schedule):
        force = replace(force, duration_steps=reading.hold_steps)
    if case in TABLE1_SCENARIOS:
        ranges = scenario.randomization if reading.robot == "test" else NOMINAL
    else:
        ranges = scaled_robot(scenario.randomization, scale)
    return replace(scenario, name=f"{case}x{scale:g}[{reading.key}]", randomization=ranges, force=force)


# ------------------------------------------------------------------------------------------ the checkpoint
def result_path(run: Path, steps: int) -> Path:
    """The measurements file of the run's checkpoint at ``steps``."""
    return Path(run) / EVALUATIONS / f"{steps}{SUFFIX}"


def result_files(run: Path) -> dict[int, Path]:
    """Every measurements file of a run folder, by the steps of the checkpoint it measured."""
    found = {}
    for path in (Path(run) / EVALUATIONS).glob(f"*{SUFFIX}"):
        steps = path.name[: -len(SUFFIX)]
        if steps.isdigit():
            found[int(steps)] = path
    return dict(sorted(found.items()))


def _git(run: Path, *args: str, out: Any = subprocess.PIPE) -> subprocess.CompletedProcess | None:
    try:
        return subprocess.run(
            ["git", "-C", str(run), *args], stdout=out, stderr=subprocess.DEVNULL, check=True
        )
    except (OSError, subprocess.CalledProcessError):
        return None


def history_commit(run: Path, steps: int, env_id: str = ZERITH1_ID) -> str | None:
    """The newest commit whose copy of the run's ``state.json`` names ``steps``: it holds the run's model and
    statistics of that step. None without git or such a commit."""
    state = f"{env_id}/state.json"
    log = _git(run, "log", "--format=%H", "--", state)
    for commit in log.stdout.decode().split() if log else ():
        shown = _git(run, "show", f"{commit}:./{state}")
        with contextlib.suppress(ValueError, AttributeError):
            if shown and json.loads(shown.stdout).get("timesteps") == steps:
                return commit
    return None


@contextlib.contextmanager
def checkpoint_files(
    run: Path, steps: int, env_id: str = ZERITH1_ID
) -> Iterator[tuple[int, Path, Path | None, str]]:
    """The run's model at ``steps`` copied into a temporary folder (a run training on replaces its newest
    model): (steps measured, model file, normalizer file or None, where it came from). See the module
    docstring for the order of the sources; ExperimentError if the run holds no model at all."""
    from sb3_huri.runner.folder import saved_models

    run = Path(run)
    with tempfile.TemporaryDirectory(prefix="force_magnitude_") as folder:
        model_copy, normalizer_copy = Path(folder) / "model.zip", Path(folder) / "vecnormalize.pkl"
        found = saved_models(run, env_id)
        commit = None if steps in found else history_commit(run, steps, env_id)
        if commit is not None:
            shown = {}
            for name, target in (
                (f"{env_id}.zip", model_copy),
                (f"{env_id}/vecnormalize.pkl", normalizer_copy),
            ):
                with open(target, "wb") as file:
                    shown[name] = _git(run, "show", f"{commit}:./{name}", out=file) is not None
            if not shown[f"{env_id}.zip"]:
                raise ExperimentError(
                    f"{run}: commit {commit} holds its state at {steps:,} steps, not its model"
                )
            normalizer = normalizer_copy if shown[f"{env_id}/vecnormalize.pkl"] else None
            yield steps, model_copy, normalizer, f"git {commit[:10]}: {env_id}.zip"
            return
        if not found:
            raise ExperimentError(f"{run} holds no model of {env_id} at {steps:,} steps nor any other")
        measured = min(found, key=lambda held: (abs(held - steps), held))
        model, normalizer = found[measured]
        shutil.copyfile(model, model_copy)
        if normalizer is not None:
            shutil.copyfile(normalizer, normalizer_copy)
        where = str(model.relative_to(run)) if model.is_relative_to(run) else str(model)
        if measured != steps:
            where += f" (no model of {steps:,} steps held: the nearest)"
        yield measured, model_copy, normalizer_copy if normalizer is not None else None, where


# ---------------------------------------------------------------------------------------------- measuring
def new_record(
    steps: int, evaluated: int, source: str, robots: int, seed: int, episode_steps: int
) -> dict[str, Any]:
    """A new file's contents: what was measured and how, and no measurement yet."""
    return {
        "env_id": ZERITH1_ID,
        "steps": steps,
        "evaluated_steps": evaluated,
        "model": source,
        "settings": {"robots": robots, "seed": seed, "episode_steps": episode_steps},
        "eval_s": 0.0,
        "measurements": {},
    }


RESUMED_KEYS = ("env_id", "steps", "settings")
"""What a file's measurements must share with a new call's for the call to add to them."""


def resumed(path: Path, record: dict[str, Any]) -> dict[str, Any]:
    """``record`` with the measurements and time of the file at ``path`` when it measured the same checkpoint
    the same way; ExperimentError if it measured it otherwise."""
    return resumed_record(
        path, record, RESUMED_KEYS, "measurements", "an agent's survival over force magnitude"
    )


def scale_key(scale: float) -> str:
    return f"{scale:g}"


def missing(
    record: dict[str, Any], readings: Sequence[Reading], cases: Sequence[str], scales: Sequence[float]
):
    """The (canonical reading, case, scale) of ``readings`` x ``cases`` x ``scales`` not measured yet, each
    once, in that order."""
    todo = []
    for reading in readings:
        for case in cases:
            canonical = reading.canonical(case)
            done = record["measurements"].get(canonical.key, {}).get(case, {})
            todo += [(canonical, case, s) for s in scales if scale_key(s) not in done]
    return list(dict.fromkeys(todo))


def measure_agent(
    run: Path,
    steps: int,
    readings: Sequence[Reading] = (HEADLINE,),
    *,
    cases: Sequence[str] = CASES,
    scales: Sequence[float] = SCALES,
    robots: int = DEFAULT_ROBOTS,
    seed: int = DEFAULT_SEED,
    episode_steps: int | None = None,
    deadline: float | None = None,
) -> Path:
    """Measure the agent of ``run`` at ``steps`` (``checkpoint_files``) in every case, scale and reading not
    measured yet; return its file's path. ``robots`` episodes per case and scale, robot i seeded ``seed + i``;
    ``episode_steps``: the time limit (default the env's, 20 s); ``deadline`` (``time.time()``): start no
    case-scale after it (the rest is measured by the next call). A file of other settings is refused
    (ExperimentError) rather than overwritten."""
    from sb3_huri.runner.folder import load_checkpoint
    from zerith_gym.core.task import EPISODE_STEPS

    for case in cases:
        _schedule(case)  # unknown cases fail before anything is loaded
    run = Path(run)
    with checkpoint_files(run, steps) as (measured, model_file, normalizer_file, source):
        path = result_path(run, measured)
        limit = episode_steps or EPISODE_STEPS
        record = resumed(path, new_record(measured, steps, source, robots, seed, limit))
        todo = missing(record, readings, cases, scales)
        print(f"{run}: {measured:,} steps ({source}), {len(todo)} case-scales to measure", flush=True)
        if not todo:
            return path
        model, normalizer = load_checkpoint(model_file, normalizer_file)
        if model.num_timesteps != measured:
            raise ExperimentError(f"{run}: its model at {measured:,} steps holds {model.num_timesteps:,}")
    for reading, case, scale in todo:
        if deadline is not None and time.time() >= deadline:
            break
        began = time.process_time()
        result = evaluate(
            model, normalizer, stressed(case, scale, reading), None, robots, seed,
            episode_steps=episode_steps, workers=0, per_robot=True,
        )  # fmt: skip
        fall = [None if math.isnan(step) else int(step) for step in result["fall_step"]]
        cell = {"survive": result["survive"], "fall_step": fall}
        record["measurements"].setdefault(reading.key, {}).setdefault(case, {})[scale_key(scale)] = cell
        record["eval_s"] += time.process_time() - began
        path.parent.mkdir(parents=True, exist_ok=True)
        write_json(path, record)
        print(f"  {reading.key:<22} {case:<20} x{scale:<5g} survive {result['survive']:.3f}", flush=True)
    return path


# --------------------------------------------------------------------------------------- reading the files
def read_record(path: Path) -> dict[str, Any]:
    """A measurements file (ExperimentError if it is not one)."""
    record = read_json(path, "an agent's survival over force magnitude")
    if not isinstance(record, dict) or not isinstance(record.get("measurements"), dict):
        raise ExperimentError(f"{path} holds no measurements; delete it to measure anew")
    return record


def survived(record: dict[str, Any], reading: Reading, case: str) -> dict[float, np.ndarray]:
    """Each robot's outcome (True: no fall) by scale, in increasing order, of ``case`` under ``reading``."""
    cells = record["measurements"].get(reading.canonical(case).key, {}).get(case, {})
    by_scale = {
        float(key): np.array([step is None for step in cell["fall_step"]]) for key, cell in cells.items()
    }
    return dict(sorted(by_scale.items()))


def survival_curve(outcomes: dict[float, np.ndarray]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Scales, survival share at each and the robots it is over (``survived``'s outcomes)."""
    scales = np.array(list(outcomes), dtype=float)
    shares = np.array([alive.mean() for alive in outcomes.values()], dtype=float)
    return scales, shares, np.array([alive.size for alive in outcomes.values()], dtype=int)


def half_survival_scale(scales: Sequence[float], survival: Sequence[float], level: float = 0.5) -> float:
    """The scale at which survival first falls below ``level`` going up the scales, interpolated linearly
    between the last scale at or above it and the first below it. ``inf`` where it never falls below it;
    ``-inf`` where it is below it at the smallest scale; NaN for no scale."""
    scales, survival = np.asarray(scales, dtype=float), np.asarray(survival, dtype=float)
    if scales.size == 0:
        return math.nan
    below = np.flatnonzero(survival < level)
    if below.size == 0:
        return math.inf
    first = int(below[0])
    if first == 0:
        return -math.inf
    (s0, s1), (v0, v1) = scales[first - 1 : first + 1], survival[first - 1 : first + 1]
    return float(s0 + (v0 - level) / (v0 - v1) * (s1 - s0))


def scale_cell(value: float, scales: Sequence[float]) -> str:
    """A 50% scale as the page and the tables write it: ``0.62x``, ``> 1.5x``, ``< 0.1x``."""
    if math.isnan(value):
        return "-"
    if value == math.inf:
        return f"> {max(scales):g}x"
    if value == -math.inf:
        return f"< {min(scales):g}x"
    return f"{value:.2f}x"


def paired_curve(
    first: dict[float, np.ndarray], second: dict[float, np.ndarray]
) -> list[tuple[float, float, float, float]]:
    """(scale, first - second, low, high) at every scale both measured on the same robots: Newcombe's
    paired 95% interval."""
    rows = []
    for scale, alive in first.items():
        other = second.get(scale)
        if other is not None and other.shape == alive.shape:
            rows.append((scale, *paired_difference_interval(alive, other)))
    return rows


def table1_robot_means(record: dict[str, Any], reading: Reading, scale: float) -> np.ndarray | None:
    """Each robot's survival averaged over the six Table-1 cases at ``scale`` (None unless all six were
    measured there)."""
    outcomes = [survived(record, reading, case).get(scale) for case in TABLE1_SCENARIOS]
    if any(o is None for o in outcomes) or len({o.shape for o in outcomes}) != 1:
        return None
    return np.mean(np.array(outcomes, dtype=float), axis=0)


def table1_difference(
    first: dict[str, Any], second: dict[str, Any], reading: Reading, scale: float = PAPER_SCALE
) -> tuple[float, float, float]:
    """The Table-1 means of two agents at ``scale`` under ``reading``, ``first - second``, with a 95%
    interval: Student's t over the robots of each robot's difference averaged over the six cases (NaN if
    unmeasured)."""
    a, b = table1_robot_means(first, reading, scale), table1_robot_means(second, reading, scale)
    if a is None or b is None or a.shape != b.shape:
        return math.nan, math.nan, math.nan
    mean, half, _ = mean_ci((a - b).tolist())
    half = 0.0 if not math.isfinite(half) else half
    return mean, mean - half, mean + half


def agent_record(run: Path, steps: int) -> dict[str, Any] | None:
    """The measurements of the run's checkpoint at ``steps``, or of the model measured in its place (a file
    recording ``steps`` as its evaluated step); None if there is neither."""
    files = result_files(run)
    if steps in files:
        return read_record(files[steps])
    for path in files.values():
        record = read_record(path)
        if record.get("evaluated_steps") == steps:
            return record
    return None


def report(agents: Sequence[tuple[str, dict[str, Any]]], reading: Reading = HEADLINE) -> str:
    """Each agent's survival per case and scale under ``reading``, and its 50% scale per case, as text."""
    lines = [f"survival under {reading.label} ({reading.key}); last column: the 50% scale"]
    for name, record in agents:
        settings = record["settings"]
        lines.append(
            f"\n{name}: {record['steps']:,} steps, {settings['robots']} robots (seeds {settings['seed']}+)"
        )
        for case in CASES:
            scales, shares, _ = survival_curve(survived(record, reading, case))
            if scales.size == 0:
                continue
            cells = " ".join(f"{s:g}:{v:.2f}" for s, v in zip(scales, shares, strict=True))
            half = scale_cell(half_survival_scale(scales, shares), scales)
            lines.append(f"  {case:<20} {cells}  | {half}")
    return "\n".join(lines)
