"""Two agents on the same robots: which survives the paper's disturbances more often, and by how much.

    python -m study.scripts.compare_agents trained_agents/huri/Zerith1-v0_1 runs/huri-baseline/Zerith1-v0_1
    python -m study.scripts.compare_agents A B --episodes 100 --seed 2000 --json comparison.json

Each case (default: the six Table-1 scenarios, `side-impact` and `nominal@1.0`) runs `--episodes` robots,
robot i seeded `seed + i`, once under each agent (`sb3_huri.runner.evaluation.evaluate`, deterministic
policies), so both meet the same robots, forces and commands. Per case it prints each agent's survival,
their difference (first minus second) with a 95% paired interval (Newcombe's, from the robots' paired
outcomes), the robots only the first / only the second survived, and the exact McNemar p-value (a two-sided
binomial test on those two counts: is the split of the disagreements other than even?). The last row is the
Table-1 mean: the per-robot difference averaged over the six scenarios, with a Student-t interval over the
robots. Pairing matters: two agents that fail on the same hard robots are told apart by the few robots on
which they disagree, which unpaired intervals of each share would blur. The forward velocity at each
agent's command is printed too (`vx`, m/s; the shipping criterion asks >= 0.8 at 1 m/s).

Agents are run folders in RL Zoo's layout (`Zerith1-v0.zip`, `Zerith1-v0/vecnormalize.pkl`), trained by
any method of this package or by SB3's PPO. The work is done by `study.analyses.agents`.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import torch as th

from study.analyses.agents import COMPARED_CASES, check_cases, compare_agents, comparison_text


def main() -> None:
    """Parse and check the command line, compare the two agents and print (and write, if asked) the rows."""
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("first", type=Path, help="run folder of the first agent")
    parser.add_argument("second", type=Path, help="run folder of the second agent")
    parser.add_argument("--cases", nargs="+", default=list(COMPARED_CASES), help="scenario or scenario@vx")
    parser.add_argument("--episodes", type=int, default=100, help="robots per case (default 100)")
    parser.add_argument("--seed", type=int, default=2000, help="robot i is seeded seed + i (default 2000)")
    parser.add_argument("--json", type=Path, default=None, help="also write the rows here")
    args = parser.parse_args()
    if args.episodes < 1:
        parser.error(f"--episodes must be at least 1, got {args.episodes}")
    try:  # an unknown scenario is refused before any agent is loaded
        check_cases(args.cases)
    except ValueError as error:
        parser.error(str(error))
    th.set_num_threads(1)
    rows = compare_agents(args.first, args.second, args.cases, args.episodes, args.seed)
    print(f"first: {args.first}  second: {args.second}")
    print(f"{args.episodes} robots per case, seeds {args.seed}-{args.seed + args.episodes - 1}")
    print(comparison_text(rows))
    if args.json is not None:
        args.json.write_text(json.dumps(rows, indent=1))


if __name__ == "__main__":
    main()
