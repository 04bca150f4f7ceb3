"""The results page's text and tables: what the numbers show, the campaign's status, the Table-1 analog and
the paired differences."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from sb3_huri.experiments import paper
from sb3_huri.experiments.markdown import interval_cell, table
from sb3_huri.experiments.statistics import mean_ci, paired_difference_interval
from sb3_huri.runner.evaluation import TABLE1_SCENARIOS
from sb3_huri.runner.files import read_json
from sb3_huri.runner.record import EVALUATIONS, PARTIAL
from study.campaign import progress
from study.campaign.final_evaluation import evaluation_cases
from study.campaign.queue import PROTOCOLS, CampaignEntry
from study.results.evaluations import (
    BASELINE,
    SURVIVAL_CASES,
    Evaluated,
    comparable,
    later_checkpoints,
    mean_difference,
    method_label,
    pairs,
    table1_mean,
)
from study.results.markdown import (
    difference_cell,
    link,
    millions,
    share_cell,
    verdict,
)
from study.results.sections import heading, section


def findings_section(
    entries: Sequence[CampaignEntry], evaluations: Sequence[Evaluated], more: Sequence[str] = ()
) -> list[str]:
    """Generated sentences: what the evaluations show, and what they cannot show yet; ``more``: further
    findings (lines of the list) of other robots' sections."""
    lines = ["## What the numbers show, and what they do not", ""]
    over_seeds = seed_comparisons(pairs(evaluations))
    lines += [f"- **{comparison.sentence()}**" for comparison in over_seeds]
    if not over_seeds:
        lines.append(
            "- **Every comparison below rests on one seed per method**: no protocol has two seeds of a "
            "method and of PPO evaluated at comparable steps yet, so no claim here holds over seeds."
        )
    states = {entry.name: progress.state(entry) for entry in entries}
    done = [name for name, state in states.items() if state in ("done", "measure")]
    lines.append(
        f"- {len(done)} of {len(entries)} entries evaluated" + (f": {', '.join(done)}." if done else ".")
    )
    for state, words in (
        ("train", "still training"),
        ("evaluate", "trained, waiting for their evaluation"),
        ("measure", "evaluated, their risk levels or force-magnitude curves still being measured"),
    ):
        names = [name for name, s in states.items() if s == state]
        if names:
            lines.append(f"- {words.capitalize()}: {', '.join(names)}.")
    for first, second in pairs(evaluations):
        lines.append(f"- {_pair_sentence(first, second)}")
    if not pairs(evaluations):
        lines.append(
            "- No HuRi-PPO pair is evaluated yet (same protocol and seed, checkpoints at most one rollout "
            "apart): nothing here compares the methods."
        )
    for later, earlier in later_checkpoints(evaluations):
        mean, low, high = mean_difference(later, earlier)
        lines.append(
            f"- {later.entry.name} at {millions(later.steps)} minus the same run at "
            f"{millions(earlier.steps)} ({earlier.entry.name}), Table-1 mean on the same robots: "
            f"{difference_cell(mean, low, high)}: "
            + verdict(low, high, "the later checkpoint", "the earlier checkpoint")
            + "."
        )
    for (protocol, method), seeds in _seeds(evaluations).items():
        if len(seeds) < 2:
            lines.append(
                f"- {method_label(method)}, {protocol} protocol: one seed ({seeds[0]}): an anecdote, no "
                "interval over seeds yet."
            )
    return [*lines, *more, ""]


def _seeds(evaluations: Sequence[Evaluated]) -> dict[tuple[str, str], list[int]]:
    """The evaluated seeds of each (protocol, method)."""
    seeds: dict[tuple[str, str], list[int]] = {}
    for e in evaluations:
        known = seeds.setdefault((e.entry.protocol, e.entry.method), [])
        if e.entry.seed not in known:
            known.append(e.entry.seed)
    return seeds


def _pair_sentence(first: Evaluated, second: Evaluated) -> str:
    """The finding of one pair: its Table-1 mean difference and what the interval says."""
    mean, low, high = mean_difference(first, second)
    name = method_label(first.entry.method)
    return (
        f"{name} minus PPO, {first.entry.protocol} protocol, seed {first.entry.seed} "
        f"({millions(first.steps)} vs {millions(second.steps)} steps), Table-1 mean on the same robots: "
        f"{difference_cell(mean, low, high)}: " + verdict(low, high, name, "PPO") + "."
    )


def _evaluating(entry: CampaignEntry) -> int | None:
    """Cases done of the entry's evaluation under way (a ``.json.partial`` file), or None."""
    for path in sorted((entry.run / EVALUATIONS).glob(f"*.json{PARTIAL}")):
        data = read_json(path, "a final evaluation under way")
        if data.get("entry") == entry.name:
            return len(data.get("cases", {}))
    return None


def _entry_status(entry: CampaignEntry, evaluated: Evaluated | None) -> tuple[int, float, list[str], str]:
    """Steps the run trained, training hours (up to the evaluated checkpoint once evaluated), the
    hardware of those hours and the entry's state in words."""
    from sb3_huri.runner.state import RunState

    run = RunState.read(entry.run, entry.env_id)
    state = progress.state(entry)
    if evaluated is not None:
        hours, hardware = (
            evaluated.data.get("wall_s", math.nan) / 3600,
            list(evaluated.data.get("hardware", [])),
        )
        words = "analyses pending" if state == "measure" else "done"
        return run.timesteps, hours, hardware, f"{words} (evaluated at {evaluated.steps:,})"
    cases = _evaluating(entry)
    if state == "evaluate" and cases is not None:
        state = f"evaluating ({cases} of {len(evaluation_cases(entry))} cases)"
    return run.timesteps, run.wall_s / 3600, run.hardware_until(run.timesteps + 1), state


def status_section(
    entries: Sequence[CampaignEntry], evaluations: Sequence[Evaluated], out: Path
) -> list[str]:
    """The status section: every entry of the queue, in its order."""
    lines = [
        heading("status", "Campaign status"),
        "",
        "In queue order. Steps: what the run folder holds / the entry's target. Training hours and hardware: "
        "the run's sessions (`state.json`) up to the evaluated checkpoint once the entry is evaluated, up to "
        "now otherwise. A run folder may serve several entries (trained to one target, later on to another).",
        "",
    ]
    by_entry = {e.entry.name: e for e in evaluations}
    rows = []
    for entry in entries:
        steps, hours, hardware, state = _entry_status(entry, by_entry.get(entry.name))
        run = f"`{link(entry.run, out)}`"
        cells = [entry.name, entry.protocol, method_label(entry.method), str(entry.seed), run]
        cells += [f"{steps:,} / {entry.steps:,}", f"{hours:.2f}", "; ".join(hardware) or "-", state]
        rows.append(cells)
    header = ["entry", "protocol", "method", "seed", "run", "steps / target", "training h", "hardware"]
    return [*lines, *table([*header, "state"], rows), ""]


def _clusters(group: Sequence[Evaluated]) -> list[list[Evaluated]]:
    """Evaluations grouped by step (each within one rollout of its group's first), one per seed."""
    clusters: list[list[Evaluated]] = []
    for evaluated in sorted(group, key=lambda e: e.steps):
        if clusters and comparable(clusters[-1][0], evaluated):
            if evaluated.entry.seed not in {e.entry.seed for e in clusters[-1]}:
                clusters[-1].append(evaluated)
        else:
            clusters.append([evaluated])
    return clusters


def survival_cell(evaluated: Evaluated, case: str) -> str:
    """The share of robots that survived ``case`` with its 95% Wilson interval ("-" if not evaluated)."""
    outcomes = evaluated.survived(case)
    return "-" if outcomes is None else share_cell(float(outcomes.mean()), outcomes.size)


def _table1_row(evaluated: Evaluated) -> list[str]:
    """One agent's row of the Table-1 analog: each case with its Wilson interval, the mean with its t one."""
    cells = [survival_cell(evaluated, case) for case in SURVIVAL_CASES]
    mean, low, high = table1_mean(evaluated)
    cells.insert(len(TABLE1_SCENARIOS), "-" if math.isnan(mean) else interval_cell(mean, low, high, ".3f"))
    entry = evaluated.entry
    return [entry.name, str(entry.seed), f"{evaluated.steps:,}", *cells]


def _seed_row(cluster: Sequence[Evaluated]) -> list[str]:
    """Mean over seeds of one step, with the half width of its 95% t interval over the seeds."""
    cells = []
    for case in SURVIVAL_CASES:
        mean, half, n = mean_ci([e.metric(case, "survive") for e in cluster])
        cells.append(f"{mean:.3f} ± {half:.3f} ({n})" if n > 1 else "-")
    mean, half, n = mean_ci([table1_mean(e)[0] for e in cluster])
    cells.insert(len(TABLE1_SCENARIOS), f"{mean:.3f} ± {half:.3f} ({n})" if n > 1 else "-")
    seeds = ", ".join(str(seed) for seed in sorted(e.entry.seed for e in cluster))
    steps = f"~{cluster[0].steps:,}"
    return [f"**mean over seeds {seeds}**", "-", steps, *cells]


def _paper_row(method: str) -> list[str] | None:
    """The paper's Table-1 row of ``method`` (None where the paper has none)."""
    reference = paper.TABLE1.get(method)
    if reference is None:
        return None
    cells = [f"{reference[case]:.3f}" for case in TABLE1_SCENARIOS]
    cells += [f"{np.mean(list(reference.values())):.3f}", "-"]
    return [f"*paper: {method_label(method)}*", "5 seeds", "-", *cells]


def table1_section(evaluations: Sequence[Evaluated]) -> list[str]:
    """The Table-1 section: survival per case for every evaluated agent, means over seeds, the paper's
    numbers."""
    lines = [
        heading("table1", "Survival under the paper's disturbances (Table 1 analog)"),
        "",
        "Share of robots without a fall, with its 95% Wilson score interval over the robots. Table-1 mean: "
        "the mean of the six Table-1 cases, its interval Student's t over the robots of each robot's "
        "survival averaged over the six cases (the robots are the independent units: the six cases share "
        "them). `side-impact`: one 200 N push from the side (not in the paper's table). Where several seeds "
        "of a method were evaluated within one rollout of each other: their mean ± the half width of a 95% "
        "t interval over the seeds (count in parentheses). The paper's rows: its Table 1, 5 seeds x 10 runs "
        "at its own training ranges, on its own robot; they set the scale, they are not the same experiment.",
        "",
    ]
    if not evaluations:
        return [*lines, "No entry is evaluated yet.", ""]
    header = ["agent", "seed", "steps", *TABLE1_SCENARIOS, "Table-1 mean", "side-impact"]
    for protocol in PROTOCOLS:
        group = [e for e in evaluations if e.entry.protocol == protocol]
        if not group:
            continue
        rows = []
        for method in dict.fromkeys(e.entry.method for e in group):
            own = [e for e in group if e.entry.method == method]
            rows += [_table1_row(e) for e in own]
            rows += [_seed_row(cluster) for cluster in _clusters(own) if len(cluster) > 1]
            reference = _paper_row(method)
            rows += [reference] if reference else []
        lines += [f"### {protocol} protocol", "", *table(header, rows), ""]
    return lines


def case_difference(
    first: Evaluated, second: Evaluated, case: str
) -> tuple[np.ndarray, np.ndarray, tuple[float, float, float]] | None:
    """Both agents' outcomes in ``case`` and ``first - second`` with Newcombe's paired 95% interval; None
    unless both were evaluated on the same number of robots."""
    a, b = first.survived(case), second.survived(case)
    if a is None or b is None or a.shape != b.shape:
        return None
    return a, b, paired_difference_interval(a, b)


def method_pair_lines(first: Evaluated, second: Evaluated, cases: Sequence[str]) -> list[str]:
    """A method's evaluation minus PPO's on the same robots: heading and ``pair_table`` of ``cases``."""
    return [
        f"**{first.label} minus {second.label}** on the same robots ({first.entry.protocol}, seed "
        f"{first.entry.seed}; Newcombe's paired 95% interval per case, as in {section('table1')})",
        "",
        *pair_table(first, second, method_label(first.entry.method), "PPO", cases),
    ]


def pair_table(
    first: Evaluated,
    second: Evaluated,
    first_name: str,
    second_name: str,
    cases: Sequence[str] = SURVIVAL_CASES,
) -> list[str]:
    """Per case of ``cases`` both hold: both shares, ``first - second`` with Newcombe's paired 95% interval,
    the robots only one of them survived; then, where ``cases`` and both evaluations hold the six Table-1
    cases, the Table-1 mean's paired difference (t over the robots)."""
    rows = []
    for case in cases:
        paired = case_difference(first, second, case)
        if paired is None:
            continue
        a, b, (difference, low, high) = paired
        cells = [case, f"{a.mean():.2f}", f"{b.mean():.2f}", difference_cell(difference, low, high)]
        cells += [str(np.sum(a & ~b)), str(np.sum(~a & b)), verdict(low, high, first_name, second_name)]
        rows.append(cells)
    mean, low, high = mean_difference(first, second)
    if set(TABLE1_SCENARIOS) <= set(cases) and math.isfinite(mean):
        means = [f"{table1_mean(first)[0]:.3f}", f"{table1_mean(second)[0]:.3f}"]
        cells = ["Table-1 mean (t over robots)", *means]
        cells += [difference_cell(mean, low, high), "-", "-", verdict(low, high, first_name, second_name)]
        rows.append(cells)
    header = ["case", first_name, second_name, "difference [95%]", f"only {first_name} survived"]
    return [*table([*header, f"only {second_name} survived", "reading"], rows), ""]


def _waiting_pairs(entries: Sequence[CampaignEntry]) -> list[str]:
    """Entries of a method and of PPO with the same protocol, seed and target whose evaluations are not
    both written yet, with their states."""
    waiting = []
    for first in entries:
        for second in entries:
            matched = (first.protocol, first.seed, first.steps) == (
                second.protocol,
                second.seed,
                second.steps,
            )
            if first.method != BASELINE and second.method == BASELINE and matched:
                states = (progress.state(first), progress.state(second))
                if not {*states} <= {"done", "measure"}:
                    waiting.append(f"{first.name} ({states[0]}) with {second.name} ({states[1]})")
    return waiting


def pairs_section(entries: Sequence[CampaignEntry], evaluations: Sequence[Evaluated]) -> list[str]:
    """The Table-1 section's paired comparisons: HuRi minus PPO, and later minus earlier checkpoints of a
    run."""
    lines = [
        "### Paired differences on the same robots",
        "",
        "Both agents met the same robots (same seeds, forces and commands), so only the robots on which "
        "they disagree move the difference. Per case: Newcombe's hybrid score interval for paired "
        "proportions (95%); Table-1 mean: Student's t over the robots of each robot's difference averaged "
        "over the six cases. An interval that includes 0 measures no difference; it does not show that "
        "there is none. Seven cases are tested at once: at 95% each, one interval in twenty excludes 0 by "
        "chance alone.",
        "",
    ]
    found = pairs(evaluations)
    for first, second in found:
        name = method_label(first.entry.method)
        lines += [
            f"**{first.label} minus {second.label}** ({first.entry.protocol}, seed {first.entry.seed})",
            "",
        ]
        lines += pair_table(first, second, name, "PPO")
    if not found:
        lines += ["No pair of a method and PPO is evaluated at comparable steps yet.", ""]
    waiting = _waiting_pairs(entries)
    if waiting:
        lines += ["Pairs still waiting: " + "; ".join(waiting) + ".", ""]
    lines += _seed_differences(found)
    for later, earlier in later_checkpoints(evaluations):
        lines += [f"**{later.label} minus {earlier.label}**: the same run trained on, on the same robots", ""]
        lines += pair_table(later, earlier, millions(later.steps), millions(earlier.steps))
    return lines


@dataclass(frozen=True)
class SeedComparison:
    """A method against PPO over the seeds of one protocol paired at comparable steps: each seed's paired
    Table-1 mean difference on the same robots, and their mean with a 95% t interval over the seeds."""

    protocol: str
    method: str
    pairs: tuple[tuple[Evaluated, Evaluated], ...]
    differences: tuple[tuple[float, float, float], ...]
    """Each seed's ``(difference, low, high)``: the interval over its robots."""
    mean: float
    half: float
    """Half width of the 95% Student's t interval of ``mean`` over the seeds."""

    @property
    def seeds(self) -> list[int]:
        return [first.entry.seed for first, _ in self.pairs]

    @property
    def below(self) -> int:
        """Seeds whose difference is below 0 (the method survived less than PPO)."""
        return sum(difference < 0 for difference, _, _ in self.differences)

    def sentence(self) -> str:
        """The comparison in one sentence, its count of seeds first."""
        name = method_label(self.method)
        low, high = self.mean - self.half, self.mean + self.half
        return (
            f"Over {len(self.pairs)} seeds ({', '.join(map(str, self.seeds))}), {name} minus PPO, "
            f"{self.protocol} protocol, ~{millions(self.pairs[0][0].steps)} steps, Table-1 mean on the same "
            f"robots: {difference_cell(self.mean, low, high)} (95% t interval over the seeds); below 0 in "
            f"{self.below} of {len(self.pairs)} seeds: " + verdict(low, high, name, "PPO") + "."
        )


def seed_comparisons(found: Sequence[tuple[Evaluated, Evaluated]]) -> list[SeedComparison]:
    """Every (protocol, method) with at least two seeds paired with PPO at comparable steps (``pairs``),
    one comparison per group of comparable steps."""
    groups: dict[tuple[str, str], list[tuple[Evaluated, Evaluated]]] = {}
    for first, second in found:
        groups.setdefault((first.entry.protocol, first.entry.method), []).append((first, second))
    comparisons = []
    for (protocol, method), members in groups.items():
        for cluster in _clusters([first for first, _ in members]):
            if len(cluster) < 2:
                continue
            chosen = tuple(next(p for p in members if p[0] is first) for first in cluster)
            differences = tuple(mean_difference(a, b) for a, b in chosen)
            mean, half, _ = mean_ci([difference for difference, _, _ in differences])
            comparisons.append(SeedComparison(protocol, method, chosen, differences, mean, half))
    return comparisons


def _seed_differences(found: Sequence[tuple[Evaluated, Evaluated]]) -> list[str]:
    """The seed-level comparison of each protocol and method with two or more paired seeds: each seed's
    paired difference, their mean with a t interval over the seeds, the count of seeds."""
    comparisons = seed_comparisons(found)
    if not comparisons:
        return []
    lines = [
        "### Over seeds",
        "",
        "Each seed's Table-1 mean difference is paired on the same robots (its interval is over those "
        "robots, as above); the mean over seeds has a 95% Student's t interval over the seeds, which are "
        "the independent units here. With two or three seeds that interval is wide: it says how little "
        "the seeds agree, not that the methods are equal.",
        "",
    ]
    for comparison in comparisons:
        name = method_label(comparison.method)
        rows = [
            [first.entry.seed, f"{first.steps:,} / {second.steps:,}", difference_cell(*difference)]
            for (first, second), difference in zip(comparison.pairs, comparison.differences, strict=True)
        ]
        low, high = comparison.mean - comparison.half, comparison.mean + comparison.half
        mean = difference_cell(comparison.mean, low, high)
        rows.append([f"**mean over {len(comparison.pairs)} seeds** (t over seeds)", "-", mean])
        header = ["seed", f"steps ({name} / PPO)", "difference, Table-1 mean [95% over robots]"]
        lines += [
            f"**{name} minus PPO over seeds** ({comparison.protocol} protocol)",
            "",
            *table(header, rows),
            "",
            f"- {comparison.sentence()}",
            "",
        ]
    return lines
