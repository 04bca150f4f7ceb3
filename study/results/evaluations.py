"""The campaign's final evaluations as the results page reads them, and the statistics drawn from them:
which evaluations pair, the Table-1 mean per robot and its intervals."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from sb3_huri.experiments import paper
from sb3_huri.experiments.errors import ExperimentError
from sb3_huri.experiments.statistics import mean_ci
from sb3_huri.runner.curve import read_curve
from sb3_huri.runner.evaluation import PLANE_CASE, TABLE1_SCENARIOS
from sb3_huri.runner.files import read_json
from study.campaign.queue import CampaignEntry, load_queue
from study.results.markdown import (
    millions,
)
from zerith_gym import ZERITH1_ID

BASELINE = "huri-baseline"
"""The method every other is paired against: PPO with the same networks and recipe."""


SURVIVAL_CASES = (*TABLE1_SCENARIOS, "side-impact")


TRACKING_CASES = ("load", "friction", "load-friction")


PUSH_CASE = "sudden-centroid"


RISK_LABELS = {PLANE_CASE: "plane", PUSH_CASE: "push", "uneven": "uneven"}


FIGURE_DPI = 90


METHOD_COLORS = {"huri": "tab:orange", "huri-percentile": "tab:green", BASELINE: "tab:blue"}


PROTOCOL_STYLES = {"robust": "-", "robust-256": "-.", "paper": "--", "terrain": ":"}


@dataclass(frozen=True)
class Evaluated:
    """An entry's final evaluation (``<run>/evaluations/<steps>.json``) and its run's rollout size."""

    entry: CampaignEntry
    path: Path
    data: dict[str, Any]
    rollout: int
    """Samples per rollout of the run (``n_envs * n_steps``): checkpoints closer than this are one step."""

    @property
    def steps(self) -> int:
        """The evaluated checkpoint's step."""
        return int(self.data["steps"])

    @property
    def label(self) -> str:
        """The agent's name on the page: entry and step."""
        return f"{self.entry.name} @ {millions(self.steps)}"

    def survived(self, case: str) -> np.ndarray | None:
        """Each robot's outcome (True: no fall) in ``case``, or None if the case was not evaluated."""
        record = self.data["cases"].get(case)
        return None if record is None else np.asarray(record["survived"], dtype=bool)

    def metric(self, case: str, key: str) -> float:
        """A metric of ``case`` (NaN where missing)."""
        return float(self.data["cases"].get(case, {}).get(key, math.nan))


def rollout_size(run: Path, env_id: str = ZERITH1_ID) -> int:
    """``n_envs * n_steps`` of the run's preset (``<run>/<env_id>/config.yml``); 0 if it cannot be read,
    so that only checkpoints at the very same step count as comparable."""
    path = run / env_id / "config.yml"
    try:
        config = yaml.safe_load(path.read_text()) if path.is_file() else None
    except yaml.YAMLError:
        return 0
    if isinstance(config, list):  # RL Zoo writes an ordered mapping as a list of pairs
        config = dict(config)
    if not isinstance(config, dict):
        return 0
    return int(config.get("n_envs", 0)) * int(config.get("n_steps", 0))


def load_evaluations(entries: Sequence[CampaignEntry]) -> list[Evaluated]:
    """The final evaluations written for ``entries``, in queue order (ExperimentError if one is corrupt)."""
    found = []
    for entry in entries:
        path = entry.evaluation()
        if path is None:
            continue
        data = read_json(path, "a final evaluation")
        if not isinstance(data, dict) or not isinstance(data.get("cases"), dict) or "steps" not in data:
            raise ExperimentError(f"{path} is not a final evaluation (no steps or cases); delete it")
        found.append(Evaluated(entry, path, data, rollout_size(entry.run, entry.env_id)))
    return found


def comparable(first: Evaluated, second: Evaluated) -> bool:
    """Two evaluations of checkpoints at most one rollout apart, on the same robots (same settings)."""
    gap = max(first.rollout, second.rollout)
    return abs(first.steps - second.steps) <= gap and first.data["settings"] == second.data["settings"]


def method_label(method: str) -> str:
    """The paper's name of a method (``huri-baseline`` -> ``Baseline (PPO)``)."""
    return paper.LABELS.get(method, method)


def _robot_means(evaluated: Evaluated) -> np.ndarray | None:
    """Each robot's survival averaged over the six Table-1 cases (None unless all six were evaluated)."""
    outcomes = [evaluated.survived(case) for case in TABLE1_SCENARIOS]
    if any(o is None for o in outcomes):
        return None
    return np.mean(np.array(outcomes, dtype=float), axis=0)


def table1_mean(evaluated: Evaluated) -> tuple[float, float, float]:
    """The Table-1 mean of one evaluation with a 95% interval: Student's t over the robots of each robot's
    survival averaged over the six cases (the robots are the independent units; the cases share them)."""
    means = _robot_means(evaluated)
    if means is None:
        return math.nan, math.nan, math.nan
    mean, half, _ = mean_ci(means.tolist())
    half = 0.0 if not math.isfinite(half) else half
    return mean, max(mean - half, 0.0), min(mean + half, 1.0)


def _recipe(evaluated: Evaluated) -> tuple[str, Path, int]:
    """What two evaluations must share to pair: protocol, preset and seed."""
    return evaluated.entry.protocol, evaluated.entry.conf, evaluated.entry.seed


def pairs(evaluations: Sequence[Evaluated]) -> list[tuple[Evaluated, Evaluated]]:
    """(method, PPO) evaluations of the same protocol, preset and seed, at most one rollout apart, on the
    same robots: every method other than the baseline against the baseline."""
    found = []
    for first in evaluations:
        if first.entry.method == BASELINE:
            continue
        for second in evaluations:
            same = _recipe(second) == _recipe(first)
            if second.entry.method == BASELINE and same and comparable(first, second):
                found.append((first, second))
    return found


def later_checkpoints(evaluations: Sequence[Evaluated]) -> list[tuple[Evaluated, Evaluated]]:
    """(later, earlier) evaluations of the same run on the same robots: what training on bought."""
    found = []
    for later in evaluations:
        earlier = [
            e
            for e in evaluations
            if e.entry.run == later.entry.run
            and e.steps < later.steps
            and e.data["settings"] == later.data["settings"]
        ]
        if earlier:
            found.append((later, max(earlier, key=lambda e: e.steps)))
    return found


def mean_difference(first: Evaluated, second: Evaluated) -> tuple[float, float, float]:
    """Paired difference of the Table-1 means, ``first - second``, with a 95% interval: Student's t over
    the robots of each robot's difference averaged over the six cases."""
    a, b = _robot_means(first), _robot_means(second)
    if a is None or b is None or a.shape != b.shape:
        return math.nan, math.nan, math.nan
    mean, half, _ = mean_ci((a - b).tolist())
    half = 0.0 if not math.isfinite(half) else half
    return mean, mean - half, mean + half


def runs_of(entries: Sequence[CampaignEntry]) -> dict[Path, list[CampaignEntry]]:
    """Every run folder of the queue, once, with the entries that train it (queue order)."""
    runs: dict[Path, list[CampaignEntry]] = {}
    for entry in entries:
        runs.setdefault(entry.run, []).append(entry)
    return runs


def smoothed_curve(run: Path, window: int = 50, column: str = "ep_return") -> tuple[np.ndarray, np.ndarray]:
    """The run's training return (``curve.csv``'s ``ep_return``, SB3's mean over the last 100 episodes; or
    another ``column`` of the curve) against samples, a moving average over ``window`` rollouts."""
    from scipy.ndimage import uniform_filter1d

    rows = [row for row in read_curve(run) if math.isfinite(row[column])]
    if not rows:
        return np.empty(0), np.empty(0)
    steps = np.array([row["timesteps"] for row in rows])
    returns = np.array([row[column] for row in rows])
    return steps, uniform_filter1d(returns, size=min(window, len(returns)), mode="nearest")


@dataclass(frozen=True)
class Agent:
    """An evaluated Zerith-1 agent of the campaign: a run at the step of its final evaluation."""

    names: tuple[str, ...]
    """The queue's entries evaluated at this checkpoint."""
    run: Path
    steps: int
    paired: bool
    """Whether its evaluation pairs with another method's (``results.evaluations.pairs``)."""


def campaign_agents(queue_path: Path) -> list[Agent]:
    """Every evaluated Zerith-1 agent of the queue (entries of env Zerith1-v0 with an ``evaluations/<steps>
    .json``), each checkpoint once, in queue order."""
    evaluations = load_evaluations([e for e in load_queue(Path(queue_path)) if e.env_id == ZERITH1_ID])
    paired = {id(e) for pair in pairs(evaluations) for e in pair}
    agents: dict[tuple[Path, int], Agent] = {}
    for e in evaluations:
        key = (e.entry.run, e.steps)
        known = agents.get(key)
        names = (*known.names, e.entry.name) if known else (e.entry.name,)
        agents[key] = Agent(names, e.entry.run, e.steps, id(e) in paired or bool(known and known.paired))
    return list(agents.values())
