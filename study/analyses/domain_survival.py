"""Which robots fall: an agent's survival per Table-1 case against the domain parameters each robot drew.

The test scenarios draw every robot's friction, load and centre-of-mass offset from Table 5's test ranges,
so a Table-1 share mixes easy robots with hard ones. ``survival_by_domain`` runs one episode per robot and
case (robot i seeded ``seed + i``: the same robots in every case and for every agent, as the robustness
curve's) and reports survival per bin of one parameter, and, for every parameter that varies, the
point-biserial correlation of falling with it: a strong r says that parameter, not the policy's luck,
decides which robots fall. ``study.scripts.survival_by_domain`` is the command line.
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence
from dataclasses import fields
from typing import Any

import numpy as np

from sb3_huri.runner.evaluation import evaluate, parse_case
from zerith_gym.core.randomization import DOMAIN_VECTOR_SIZE, DomainParams

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


def parameter_names() -> list[str]:
    """The names `scalar_parameters` gives, in its order: what a survival table may be binned by."""
    return list(scalar_parameters(DomainParams.from_vector(np.zeros((1, DOMAIN_VECTOR_SIZE)))))


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


def bin_labels(edges: np.ndarray) -> list[str]:
    """The bins' column labels, `[low, high)`, the last closed: `[low, high]`."""
    labels = [f"[{low:g}, {high:g})" for low, high in itertools.pairwise(edges)]
    labels[-1] = labels[-1][:-1] + "]"  # the last bin holds its upper edge
    return labels


def survival_by_domain(
    model: Any,
    normalizer: Any | None,
    cases: Sequence[str],
    robots: int,
    seed: int,
    parameter: str,
    edges: np.ndarray,
) -> str:
    """Evaluate `robots` episodes per case and return two markdown tables: survival per bin of
    `parameter` (bin `edges`), and the correlation of falling with every parameter that varies."""
    labels = bin_labels(edges)
    lines = [
        f"Survival per bin of {parameter} ({robots} robots per case, seeds {seed}+; robots):",
        f"| case | all | {' | '.join(labels)} |",
        "|" + "---|" * (len(labels) + 2),
    ]
    correlations = {}
    for case in cases:
        scenario, command = parse_case(case)
        result = evaluate(model, normalizer, scenario, command, robots, seed, workers=0, per_robot=True)
        values = scalar_parameters(result["domain"])
        survived = np.isnan(result["fall_step"])
        cells = survival_per_bin(values[parameter], survived, edges)
        lines.append(
            f"| {case} | {survived.mean():.2f} | " + " | ".join(f"{s:.2f} ({n})" for s, n in cells) + " |"
        )
        correlations[case] = fall_correlations(values, ~survived)
        print(f"{case}: {survived.mean():.2f} survive", flush=True)
    names = [n for n in parameter_names() if any(n in c for c in correlations.values())]
    if names:
        lines += ["", "Correlation of falling with each parameter (point-biserial r, p-value):"]
        lines += [f"| case | {' | '.join(names)} |", "|" + "---|" * (len(names) + 1)]
        for case, found in correlations.items():
            cells = [f"{found[n][0]:+.2f} (p {found[n][1]:.3f})" if n in found else "-" for n in names]
            lines.append(f"| {case} | {' | '.join(cells)} |")
    return "\n".join(lines)
