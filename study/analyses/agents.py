"""Trained agents evaluated case by case, and two agents compared on the same robots.

``evaluate_agents`` re-evaluates run folders (RL Zoo's layout: ``Zerith1-v0.zip``,
``Zerith1-v0/vecnormalize.pkl``) on cases ``scenario@vx`` or ``scenario``: survival with its 95% Wilson
interval, velocity tracking and gait (``sb3_huri.runner.evaluation.evaluate``, deterministic
policies, robot i seeded ``seed + i`` so that every agent meets the same conditions).

``compare_agents`` runs two agents on the same robots, forces and commands and pairs their outcomes: per
case the difference of survival (first minus second) with Newcombe's paired 95% interval, the robots only
one of them survived and the exact McNemar p-value (a two-sided binomial test on those two counts), and the
Table-1 mean's per-robot difference with a Student-t interval over the robots. Pairing matters: two agents
that fail on the same hard robots are told apart by the few robots on which they disagree, which unpaired
intervals of each share would blur.

``study.scripts.eval_agents`` and ``study.scripts.compare_agents`` are the command lines.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np

from sb3_huri.experiments.statistics import mean_ci, paired_difference_interval, wilson_interval
from sb3_huri.runner.evaluation import TABLE1_SCENARIOS, evaluate, parse_case
from sb3_huri.runner.folder import load_run
from zerith_gym import ZERITH1_ID

COMPARED_CASES = (*TABLE1_SCENARIOS, "side-impact", "nominal@1.0")
"""The cases two agents are compared on by default: Table 1, the side impact and the plane at 1 m/s."""
Outcomes = dict[str, tuple[np.ndarray, float]]
"""Per case: each robot's survival (robots,) and the mean forward velocity."""


def check_cases(cases: Sequence[str]) -> list[tuple[str, Any, tuple[float, float, float] | None]]:
    """Each case with its scenario and command; a ValueError names the first unknown scenario, before any
    agent is loaded or evaluated."""
    return [(case, *parse_case(case)) for case in cases]


@dataclass
class CaseResult:
    """One agent's evaluation on one case (the columns of ``study.scripts.eval_agents``)."""

    agent: str
    case: str
    episodes: int
    survive: float
    low: float
    high: float
    vx_err: float
    vx: float
    lin_err: float
    yaw_err: float
    steps_per_s: float
    alternation: float
    single_support: float


RESULT_COLUMNS = ("survive", "low", "high", "vx_err", "vx", "lin_err", "yaw_err", "steps/s", "alt", "1-supp")
"""The printed columns of a `CaseResult`, in its field order from `survive` on."""


def evaluate_agents(
    agents: Sequence[Path],
    cases: Sequence[str],
    episodes: int,
    seed: int,
    backend_options: dict[str, Any] | None = None,
) -> list[CaseResult]:
    """Every agent on every case, `episodes` robots each; prints a row per result as it comes."""
    parsed = check_cases(cases)
    results: list[CaseResult] = []
    print(f"{'agent':<28} {'case':<22} " + " ".join(f"{c:>7}" for c in RESULT_COLUMNS))
    for folder in agents:
        model, normalizer = load_run(folder, ZERITH1_ID)
        agent = f"{folder.parent.name}/{folder.name}"
        for case, scenario, command in parsed:
            metrics = evaluate(
                model, normalizer, scenario, command, episodes, seed, backend_options=backend_options
            )
            low, high = wilson_interval(metrics["survive"], episodes)
            result = CaseResult(agent, case, episodes, low=low, high=high, **metrics)
            results.append(result)
            values = [v for k, v in asdict(result).items() if k not in ("agent", "case", "episodes")]
            print(f"{agent:<28} {case:<22} " + " ".join(f"{v:>7.3f}" for v in values), flush=True)
    return results


def survivals(folder: Path, cases: Sequence[str], episodes: int, seed: int) -> Outcomes:
    """Each case's (robots,) survival outcomes and mean forward velocity for the agent in ``folder``."""
    model, normalizer = load_run(folder, ZERITH1_ID)
    outcomes = {}
    for case in cases:
        scenario, command = parse_case(case)
        result = evaluate(model, normalizer, scenario, command, episodes, seed, per_robot=True)
        outcomes[case] = (np.isnan(result["fall_step"]), result["vx"])
        print(f"  {folder}: {case} survive {outcomes[case][0].mean():.3f}", flush=True)
    return outcomes


def compare(first: Outcomes, second: Outcomes) -> list[dict[str, Any]]:
    """One row per case, then the Table-1 mean's row when every Table-1 scenario was evaluated."""
    from scipy import stats

    rows = []
    for case, (alive_first, vx_first) in first.items():
        alive_second, vx_second = second[case]
        difference, low, high = paired_difference_interval(alive_first, alive_second)
        only_first = int(np.sum(alive_first & ~alive_second))
        only_second = int(np.sum(~alive_first & alive_second))
        disagreements = only_first + only_second
        p_value = stats.binomtest(only_first, disagreements).pvalue if disagreements else 1.0
        rows.append(
            dict(
                case=case, first=float(alive_first.mean()), second=float(alive_second.mean()),
                difference=difference, low=low, high=high, only_first=only_first, only_second=only_second,
                p_value=float(p_value), vx_first=vx_first, vx_second=vx_second,
            )
        )  # fmt: skip
    if all(case in first for case in TABLE1_SCENARIOS):
        differences = [first[case][0].astype(float) - second[case][0] for case in TABLE1_SCENARIOS]
        per_robot = np.mean(differences, axis=0)
        difference, half_width, _ = mean_ci(per_robot.tolist())
        rows.append(
            dict(
                case="table1_mean",
                first=float(np.mean([first[case][0].mean() for case in TABLE1_SCENARIOS])),
                second=float(np.mean([second[case][0].mean() for case in TABLE1_SCENARIOS])),
                difference=difference, low=difference - half_width, high=difference + half_width,
            )
        )  # fmt: skip
    return rows


def compare_agents(first: Path, second: Path, cases: Sequence[str], episodes: int, seed: int) -> list[dict]:
    """Both agents on the same `episodes` robots per case (robot i seeded `seed + i`), compared: `compare`'s
    rows. Unknown cases are refused (ValueError) before either agent is loaded."""
    check_cases(cases)
    return compare(survivals(first, cases, episodes, seed), survivals(second, cases, episodes, seed))


def comparison_text(rows: Sequence[dict[str, Any]]) -> str:
    """`compare`'s rows as a fixed-width table, the velocities at the end of each case's row."""
    columns = ("first", "second", "difference", "low", "high", "only_first", "only_second", "p_value")
    lines = [f"{'case':<20} " + " ".join(f"{column:>11}" for column in columns) + "   vx_first vx_second"]
    for row in rows:
        cells = [f"{row[c]:>11.3f}" if c in row else f"{'':>11}" for c in columns]
        speeds = f"   {row['vx_first']:>8.3f} {row['vx_second']:>9.3f}" if "vx_first" in row else ""
        lines.append(f"{row['case']:<20} " + " ".join(cells) + speeds)
    return "\n".join(lines)
