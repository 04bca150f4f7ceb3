"""Methods side by side: where several methods of one protocol and seed are paired with the same PPO
evaluation, each one's difference to PPO beside the others', and each method's difference to the paper's
HuRi on the same robots, so that a new reading of the method (the percentile band) is judged against the
literal one directly, not only through PPO."""

from __future__ import annotations

import math
from collections.abc import Sequence

from sb3_huri.experiments.markdown import table
from study.analyses.advantages import advantages_path, measured_record, summary
from study.results.evaluations import (
    BASELINE,
    Evaluated,
    mean_difference,
    method_label,
    pairs,
)
from study.results.markdown import difference_cell, millions, verdict
from study.results.sections import section
from study.results.tables import case_difference, pair_table

REFERENCE = "huri"
"""The method every other is also compared with directly: HuRi as the paper defines it."""


def side_by_side(evaluations: Sequence[Evaluated]) -> list[tuple[Evaluated, list[Evaluated]]]:
    """(PPO's evaluation, the methods paired with it, the reference first) wherever the reference and at
    least one other method are paired with the same PPO evaluation (same protocol, preset and seed, at most
    one rollout from PPO's checkpoint, on the same robots); one evaluation per method, the first in queue
    order."""
    groups: dict[int, tuple[Evaluated, dict[str, Evaluated]]] = {}
    for method, ppo in pairs(evaluations):
        groups.setdefault(id(ppo), (ppo, {}))[1].setdefault(method.entry.method, method)
    found = []
    for ppo, methods in groups.values():
        if REFERENCE in methods and len(methods) >= 2:
            reference = methods.pop(REFERENCE)
            found.append((ppo, [reference, *methods.values()]))
    return found


def side_by_side_lines(evaluations: Sequence[Evaluated], cases: Sequence[str]) -> list[str]:
    """For each group of ``side_by_side``: a table of every method minus PPO and every other method minus
    HuRi per case of ``cases`` (and the Table-1 mean where all six are there), then each direct comparison
    with HuRi in full (``pair_table``: the robots only one of them kept up, and the reading)."""
    lines = []
    for ppo, methods in side_by_side(evaluations):
        reference, others = methods[0], methods[1:]
        comparisons = [(m, ppo) for m in methods] + [(m, reference) for m in others]
        names = [f"{_name(first)} minus {_name(second)}" for first, second in comparisons]
        agents = ", ".join(e.label for e in [*methods, ppo])
        lines += [
            f"**Methods side by side, {ppo.entry.protocol} protocol, seed {ppo.entry.seed}** ({agents}): "
            "each method minus PPO, and each minus HuRi, on the same robots (95% intervals as above).",
            "",
        ]
        rows = []
        for case in cases:
            cells = [case_difference(first, second, case) for first, second in comparisons]
            if all(cell is not None for cell in cells):
                rows.append([case, *(difference_cell(*c[2]) for c in cells)])
        means = [mean_difference(first, second) for first, second in comparisons]
        if all(math.isfinite(mean[0]) for mean in means):
            rows.append(["Table-1 mean (t over robots)", *(difference_cell(*mean) for mean in means)])
        lines += [*table(["case", *names], rows), "", *_signal_lines(methods)]
        for method in others:
            seed = f"({method.entry.protocol}, seed {method.entry.seed})"
            lines += [f"**{method.label} minus {reference.label}** {seed}", ""]
            lines += pair_table(method, reference, _name(method), _name(reference), cases)
    return lines


def _signal_lines(methods: Sequence[Evaluated]) -> list[str]:
    """How much of each method's learning signal its risk distortion turns around (the advantages section's
    measure against the neutral level, by size), where every one of ``methods`` was measured at its evaluated
    checkpoint; nothing otherwise."""
    records = [measured_record(advantages_path(m.entry.run, m.steps), shown=True) for m in methods]
    if any(record is None for record in records):
        return []
    shares = [
        f"{_name(m)} {summary(record)['neutral_weighted_sign_changes']:.3f}"
        for m, record in zip(methods, records, strict=True)
    ]
    return [
        f"Their learning signal ({section('advantages')}): the share of it, by size, that the risk "
        "distortion turns "
        "around against the neutral level: " + ", ".join(shares) + ".",
        "",
    ]


def side_by_side_section(evaluations: Sequence[Evaluated], cases: Sequence[str]) -> list[str]:
    """The Table-1 section's methods side by side (nothing until two methods share a PPO evaluation)."""
    lines = side_by_side_lines(evaluations, cases)
    return ["### Methods side by side on the same robots", "", *lines] if lines else []


def side_by_side_findings(evaluations: Sequence[Evaluated], cases: Sequence[str]) -> list[str]:
    """Lines of the page's findings: each method minus HuRi where both are paired with the same PPO
    evaluation, on the Table-1 mean where all six cases are there, else per case of ``cases``."""
    lines = []
    for _, methods in side_by_side(evaluations):
        reference = methods[0]
        for method in methods[1:]:
            name, other = _name(method), _name(reference)
            mean, low, high = mean_difference(method, reference)
            if math.isfinite(mean):
                parts = [f"Table-1 mean on the same robots: {_reading(mean, low, high, name, other)}"]
            else:
                parts = [
                    f"{case} {_reading(*paired[2], name, other)}"
                    for case in cases
                    if (paired := case_difference(method, reference, case)) is not None
                ]
            lines.append(
                f"- {name} minus {other}, {method.entry.protocol} protocol, seed {method.entry.seed} "
                f"({millions(method.steps)} vs {millions(reference.steps)} steps), " + "; ".join(parts) + "."
            )
    return lines


def _reading(difference: float, low: float, high: float, first: str, second: str) -> str:
    """A difference with its interval and what the interval says."""
    return f"{difference_cell(difference, low, high)}: {verdict(low, high, first, second)}"


def _name(evaluated: Evaluated) -> str:
    """The method's name in the tables: the paper's label, PPO for the baseline."""
    return "PPO" if evaluated.entry.method == BASELINE else method_label(evaluated.entry.method)
