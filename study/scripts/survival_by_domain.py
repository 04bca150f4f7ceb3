"""Which robots fall: an agent's survival per Table-1 case against the domain parameters each robot drew.

The test scenarios draw every robot's friction, load and centre-of-mass offset from Table 5's test ranges, so
a Table-1 share mixes easy robots with hard ones. This runs `--robots` episodes per case (robot i seeded
`--seed` + i: the same robots in every case and for every agent, as in `robustness_curve.py`) and reports

- survival per bin of one parameter (`--parameter`, default friction; `--bins`: the bin edges), and
- for every parameter that varies, the point-biserial correlation of falling with it (r and its p-value):
  a strong r says that parameter, not the policy's luck, decides which robots fall.

    python -m study.scripts.survival_by_domain runs/huri/Zerith1-v0_3
    python -m study.scripts.survival_by_domain runs/huri/Zerith1-v0_3 --parameter added_mass --bins -3 0 3 8
    python -m study.scripts.survival_by_domain runs/huri/Zerith1-v0_3 --cases continuous-feet --robots 200

The friction binned and correlated is the drawn sole material; a sole slides at its mean with the ground's 1
(`zerith_gym.core.physics.contact_friction`). The work is done by `study.analyses.domain_survival`.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import torch as th

from sb3_huri.runner.evaluation import TABLE1_SCENARIOS
from sb3_huri.runner.folder import load_run
from study.analyses.agents import check_cases
from study.analyses.domain_survival import FRICTION_BINS, parameter_names, survival_by_domain
from zerith_gym import ZERITH1_ID


def main() -> None:
    """Parse and check the command line, then print the agent's survival tables."""
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("agent", type=Path, help="a run folder in RL Zoo's layout")
    parser.add_argument("--cases", nargs="+", default=list(TABLE1_SCENARIOS))
    parser.add_argument("--robots", type=int, default=100, help="episodes per case (default 100)")
    parser.add_argument("--seed", type=int, default=1000)
    parser.add_argument("--parameter", default="friction", help="the parameter to bin (see the r table)")
    parser.add_argument("--bins", type=float, nargs="+", default=list(FRICTION_BINS), help="bin edges")
    args = parser.parse_args()
    edges = np.array(sorted(args.bins))
    if len(edges) < 2:
        parser.error("--bins needs at least two edges")
    try:
        check_cases(args.cases)
    except ValueError as error:
        parser.error(str(error))
    parameters = parameter_names()
    if args.parameter not in parameters:
        parser.error(f"unknown --parameter {args.parameter!r}; one of {', '.join(parameters)}")
    th.set_num_threads(1)
    model, normalizer = load_run(args.agent, ZERITH1_ID)
    tables = survival_by_domain(model, normalizer, args.cases, args.robots, args.seed, args.parameter, edges)
    print(f"\n{tables}")


if __name__ == "__main__":
    main()
