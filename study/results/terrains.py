"""Zerith-1's section of the results page on terrains: the Table 9 analog (survival on the paper's
multi-terrain test) and stepping down Table 8's platforms (the paper's are the quadruped's: the quadruped
section) for every evaluated Zerith-1 agent, beside the paper's Table 9, and every HuRi-PPO pair on these
cases, paired on the same robots (the ``terrain`` protocol's are the paper's appendix A.7 training)."""

from __future__ import annotations

from collections.abc import Sequence

from sb3_huri.experiments import paper
from sb3_huri.experiments.markdown import table
from sb3_huri.runner.evaluation import TERRAIN_SCENARIOS
from study.campaign.queue import PROTOCOLS
from study.results.evaluations import Evaluated, method_label, pairs
from study.results.sections import heading, section
from study.results.tables import method_pair_lines, survival_cell

TERRAIN_PROTOCOL = "terrain"
"""The campaign protocol that trains on terrains, as the paper's Table 9 agents did."""
TABLE9_CASE = "multi-terrain"
"""Table 9's test: rough slopes up and down and discrete blocks under U[0, 100] N on the centroid."""


def terrain_section(evaluations: Sequence[Evaluated]) -> list[str]:
    """The terrains section: each evaluated agent's survival on the terrain cases, the paper's Table 9, and
    the pairs of a method and PPO on them."""
    lines = [
        heading("terrains", "Zerith-1 on terrains (Table 9 analog)"),
        "",
        "Share of robots without a fall at 1 m/s, with its 95% Wilson interval: `multi-terrain` (Table 9: "
        "rough slopes up and down and discrete blocks, robots spread over the 10 levels, U[0, 100] N on the "
        "centroid), stepping down a 0.40 / 0.45 m platform (Table 8: U[0, 100] N on the centroid redrawn "
        f"every 2 s, +-1 kg; the paper tests its quadruped there, {section('quadruped')}). The paper's "
        "Table 9 "
        "agents "
        f"trained on terrains (its appendix A.7: the `{TERRAIN_PROTOCOL}` protocol here); the other "
        "protocols train on the plane and meet terrains only here. The paper's rows: its Table 9, 4 seeds on "
        "its own robot.",
        "",
    ]
    if not evaluations:
        return [*lines, "No Zerith-1 entry is evaluated yet.", ""]
    rows = []
    for protocol in PROTOCOLS:
        for evaluated in (e for e in evaluations if e.entry.protocol == protocol):
            cells = [survival_cell(evaluated, case) for case in TERRAIN_SCENARIOS]
            entry = evaluated.entry
            rows.append([entry.name, protocol, str(entry.seed), f"{evaluated.steps:,}", *cells])
    for method, reference in paper.TERRAINS.items():
        cells = [f"{reference[case]:.3f}" if case == TABLE9_CASE else "-" for case in TERRAIN_SCENARIOS]
        rows.append([f"*paper: {method_label(method)}*", "terrains", "4 seeds", "-", *cells])
    lines += [*table(["agent", "protocol", "seed", "steps", *TERRAIN_SCENARIOS], rows), ""]
    found = pairs(evaluations)
    for first, second in found:
        lines += method_pair_lines(first, second, TERRAIN_SCENARIOS)
    if not any(first.entry.protocol == TERRAIN_PROTOCOL for first, _ in found):
        lines += [f"No HuRi-PPO pair of the `{TERRAIN_PROTOCOL}` protocol is evaluated yet.", ""]
    return lines
