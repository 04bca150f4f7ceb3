"""Two agents on the same robots: which survives the paper's disturbances more often, and by how much.

    python benchmarks/compare_agents.py trained_agents/huri/Zerith1-v0_1 runs/huri-baseline/Zerith1-v0_1
    python benchmarks/compare_agents.py A B --episodes 100 --seed 2000 --json comparison.json

Each case (default: the six Table-1 scenarios, `side-impact` and `nominal@1.0`) runs `--episodes` robots,
robot i seeded `seed + i`, once under each agent (`sb3_huri.experiments.evaluation.evaluate`, deterministic
policies), so both meet the same robots, forces and commands. Per case it prints each agent's survival,
their difference (first minus second) with a 95% paired interval (Newcombe's, from the robots' paired
outcomes), the robots only the first / only the second survived, and the exact McNemar p-value (a two-sided
binomial test on those two counts: is the split of the disagreements other than even?). The last row is the
Table-1 mean: the per-robot difference averaged over the six scenarios, with a Student-t interval over the
robots. Pairing matters: two agents that fail on the same hard robots are told apart by the few robots on
which they disagree, which unpaired intervals of each share would blur. The forward velocity at each
agent's command is printed too (`vx`, m/s; the shipping criterion asks >= 0.8 at 1 m/s).

Agents are run folders in RL Zoo's layout (`Zerith1-v0.zip`, `Zerith1-v0/vecnormalize.pkl`), trained by
any method of this package or by SB3's PPO.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np
import torch as th
from scipy import stats

from sb3_huri.experiments.evaluation import (
    TABLE1_SCENARIOS,
    evaluate,
    paired_difference_interval,
    parse_case,
)
from sb3_huri.experiments.report import mean_ci
from sb3_huri.zoo import load_run

ENV_ID = "Zerith1-v0"
DEFAULT_CASES = (*TABLE1_SCENARIOS, "side-impact", "nominal@1.0")
Outcomes = dict[str, tuple[np.ndarray, float]]
"""Per case: each robot's survival (robots,) and the mean forward velocity."""


def survivals(folder: Path, cases: list[str], episodes: int, seed: int) -> Outcomes:
    """Each case's (robots,) survival outcomes and mean forward velocity for the agent in ``folder``."""
    model, normalizer = load_run(folder, ENV_ID)
    outcomes = {}
    for case in cases:
        scenario, command = parse_case(case)
        result = evaluate(model, normalizer, scenario, command, episodes, seed, per_robot=True)
        outcomes[case] = (np.isnan(result["fall_step"]), result["vx"])
        print(f"  {folder}: {case} survive {outcomes[case][0].mean():.3f}", flush=True)
    return outcomes


def compare(first: Outcomes, second: Outcomes) -> list[dict]:
    """One row per case, then the Table-1 mean's row when every Table-1 scenario was evaluated."""
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


def print_rows(rows: list[dict]) -> None:
    columns = ("first", "second", "difference", "low", "high", "only_first", "only_second", "p_value")
    print(f"{'case':<20} " + " ".join(f"{column:>11}" for column in columns) + "   vx_first vx_second")
    for row in rows:
        cells = [f"{row[c]:>11.3f}" if c in row else f"{'':>11}" for c in columns]
        speeds = f"   {row['vx_first']:>8.3f} {row['vx_second']:>9.3f}" if "vx_first" in row else ""
        print(f"{row['case']:<20} " + " ".join(cells) + speeds)


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("first", type=Path, help="run folder of the first agent")
    parser.add_argument("second", type=Path, help="run folder of the second agent")
    parser.add_argument("--cases", nargs="+", default=list(DEFAULT_CASES), help="scenario or scenario@vx")
    parser.add_argument("--episodes", type=int, default=100, help="robots per case (default 100)")
    parser.add_argument("--seed", type=int, default=2000, help="robot i is seeded seed + i (default 2000)")
    parser.add_argument("--json", type=Path, default=None, help="also write the rows here")
    args = parser.parse_args()
    if args.episodes < 1:
        parser.error(f"--episodes must be at least 1, got {args.episodes}")
    for case in args.cases:  # an unknown scenario is refused before any agent is loaded
        try:
            parse_case(case)
        except ValueError as error:
            parser.error(str(error))
    th.set_num_threads(1)
    first = survivals(args.first, args.cases, args.episodes, args.seed)
    second = survivals(args.second, args.cases, args.episodes, args.seed)
    rows = compare(first, second)
    print(f"first: {args.first}  second: {args.second}")
    print(f"{args.episodes} robots per case, seeds {args.seed}-{args.seed + args.episodes - 1}")
    print_rows(rows)
    if args.json is not None:
        args.json.write_text(json.dumps(rows, indent=1))


if __name__ == "__main__":
    main()
