"""Which robots fall: an agent's survival per Table-1 case against the domain parameters each robot drew.

The test scenarios draw every robot's friction, load and centre-of-mass offset from Table 5's test ranges, so
a Table-1 share mixes easy robots with hard ones. This runs `--robots` episodes per case (robot i seeded
`--seed` + i: the same robots in every case and for every agent, as in `robustness_curve.py`) and reports

- survival per bin of one parameter (`--parameter`, default friction; `--bins`: the bin edges), and
- for every parameter that varies, the point-biserial correlation of falling with it (r and its p-value):
  a strong r says that parameter, not the policy's luck, decides which robots fall.

    python benchmarks/survival_by_domain.py runs/huri/Zerith1-v0_3
    python benchmarks/survival_by_domain.py runs/huri/Zerith1-v0_3 --parameter added_mass --bins -3 0 3 8
    python benchmarks/survival_by_domain.py runs/huri/Zerith1-v0_3 --cases continuous-feet --robots 200

The friction binned and correlated is the drawn sole material; a sole slides at its mean with the ground's 1
(`zerith_gym.physics.contact_friction`).
"""

from __future__ import annotations

import argparse
import itertools
from dataclasses import fields
from pathlib import Path

import numpy as np
import torch as th

from sb3_huri.experiments.evaluation import TABLE1_SCENARIOS, evaluate, parse_case
from sb3_huri.zoo import load_run
from zerith_gym.randomization import DOMAIN_VECTOR_SIZE, DomainParams

ENV_ID = "Zerith1-v0"
FRICTION_BINS = (0.1, 0.3, 0.55, 1.0, 1.5, 2.0)
"""Default bin edges for the sole's friction (contact frictions 0.55, 0.65, 0.775, 1, 1.25, 1.5)."""


def scalar_parameters(domain: DomainParams) -> dict[str, np.ndarray]:
    """One value per robot for each parameter: the CoM offset per axis, vectors (per joint or link) as
    their mean."""
    values = {}
    for field in fields(domain):
        column = np.asarray(getattr(domain, field.name))
        if field.name == "com_offset":
            values.update({f"com_offset_{axis}": column[:, i] for i, axis in enumerate("xyz")})
        else:
            values[field.name if column.shape[1] == 1 else f"{field.name}_mean"] = column.mean(axis=1)
    return values


def survival_per_bin(values: np.ndarray, survived: np.ndarray, edges: np.ndarray) -> list[tuple[float, int]]:
    """(survival share, robots) in each bin [edges[k], edges[k+1]) (the last bin closed); NaN if empty."""
    index = np.clip(np.searchsorted(edges, values, side="right") - 1, 0, len(edges) - 2)
    cells = []
    for k in range(len(edges) - 1):
        inside = index == k
        cells.append((float(survived[inside].mean()) if inside.any() else float("nan"), int(inside.sum())))
    return cells


def fall_correlations(values: dict[str, np.ndarray], fell: np.ndarray) -> dict[str, tuple[float, float]]:
    """Point-biserial r of falling with each parameter that varies, and its two-sided p-value."""
    from scipy import stats

    if fell.all() or not fell.any():
        return {}
    out = {}
    for name, column in values.items():
        if np.ptp(column) > 0:
            result = stats.pointbiserialr(fell, column)
            out[name] = (float(result.statistic), float(result.pvalue))
    return out


def main() -> None:
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
    for case in args.cases:
        try:
            parse_case(case)
        except ValueError as error:
            parser.error(str(error))
    parameters = list(scalar_parameters(DomainParams.from_vector(np.zeros((1, DOMAIN_VECTOR_SIZE)))))
    if args.parameter not in parameters:
        parser.error(f"unknown --parameter {args.parameter!r}; one of {', '.join(parameters)}")
    th.set_num_threads(1)
    model, normalizer = load_run(args.agent, ENV_ID)
    bins = [f"[{lo:g}, {hi:g})" for lo, hi in itertools.pairwise(edges)]
    bins[-1] = bins[-1][:-1] + "]"  # the last bin holds its upper edge
    survival_rows, correlations = [], {}
    for case in args.cases:
        scenario, command = parse_case(case)
        result = evaluate(
            model, normalizer, scenario, command, args.robots, args.seed, workers=0, per_robot=True
        )
        values = scalar_parameters(result["domain"])
        survived = np.isnan(result["fall_step"])
        cells = survival_per_bin(values[args.parameter], survived, edges)
        survival_rows.append(
            f"| {case} | {survived.mean():.2f} | " + " | ".join(f"{s:.2f} ({n})" for s, n in cells) + " |"
        )
        correlations[case] = fall_correlations(values, ~survived)
        print(f"{case}: {survived.mean():.2f} survive", flush=True)
    print(
        f"\nSurvival per bin of {args.parameter} ({args.robots} robots per case, seeds {args.seed}+; robots):"
    )
    print(f"| case | all | {' | '.join(bins)} |\n|" + "---|" * (len(bins) + 2))
    print("\n".join(survival_rows))
    names = [n for n in parameters if any(n in c for c in correlations.values())]
    if names:
        print("\nCorrelation of falling with each parameter (point-biserial r, p-value):")
        print(f"| case | {' | '.join(names)} |\n|" + "---|" * (len(names) + 1))
        for case, found in correlations.items():
            cells = [f"{found[n][0]:+.2f} (p {found[n][1]:.3f})" if n in found else "-" for n in names]
            print(f"| {case} | {' | '.join(cells)} |")


if __name__ == "__main__":
    main()
