"""The campaign's results page, ``docs/results.md``, generated from the queue and its run folders alone.

``write_results`` reads the queue file (``sb3_huri.experiments.queue``), each entry's run folder
(``state.json``, ``curve.csv``, ``robustness.csv``, ``config.yml``) and the final evaluations written by
``sb3_huri.experiments.final_evaluation``, and writes the page with four figures beside it
(``docs/results/``):

1. the campaign's status: every entry's steps, training hours, hardware and state;
2. the Table-1 analog: survival per case with its 95% Wilson interval, the Table-1 mean, the paper's
   numbers; HuRi minus PPO on the same robots (Newcombe's paired interval per case, a t interval over the
   robots for the Table-1 mean); means over seeds with a t interval where several seeds were evaluated;
3. ``robustness.png``: every run's robustness learning curve (``robustness.csv``'s Table-1 mean);
4. ``returns.png``: the training return against samples per method and protocol (Fig. 3 analog);
5. ``tracking.png``: velocity-tracking errors under load, friction and both (Fig. 4 analog);
6. ``risk.png``: the critic's IQR and beta on the plane, under a push and on uneven ground (Fig. 5 analog).

The sentences that say what the numbers show (and what they cannot show yet) are generated from the same
numbers: nothing on the page is typed in by hand but the fixed explanations.
"""

from __future__ import annotations

import math
import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from sb3_huri.experiments import paper
from sb3_huri.experiments.evaluation import (
    PLANE_CASE,
    RISK_CASES,
    TABLE1_SCENARIOS,
    paired_difference_interval,
    wilson_interval,
)
from sb3_huri.experiments.final_evaluation import (
    EVALUATION_CASES,
    PARTIAL,
    hardware_until,
    trace_path,
)
from sb3_huri.experiments.layout import ExperimentError, atomic_write_text, read_json
from sb3_huri.experiments.queue import ENV_ID, EVALUATIONS, PROTOCOLS, CampaignEntry, load_queue
from sb3_huri.experiments.report import final_return, mean_ci, read_trace
from sb3_huri.experiments.robustness import read_rows
from sb3_huri.zoo.curve import read_curve

BASELINE = "huri-baseline"
"""The method every other is paired against: PPO with the same networks and recipe."""
SURVIVAL_CASES = (*TABLE1_SCENARIOS, "side-impact")
TRACKING_CASES = ("load", "friction", "load-friction")
PUSH_CASE = "sudden-centroid"
RISK_LABELS = {PLANE_CASE: "plane", PUSH_CASE: "push", "uneven": "uneven"}
FIGURE_DPI = 90
METHOD_COLORS = {"huri": "tab:orange", BASELINE: "tab:blue"}
PROTOCOL_STYLES = {"robust": "-", "paper": "--", "terrain": ":"}


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
        return f"{self.entry.name} @ {_millions(self.steps)}"

    def survived(self, case: str) -> np.ndarray | None:
        """Each robot's outcome (True: no fall) in ``case``, or None if the case was not evaluated."""
        record = self.data["cases"].get(case)
        return None if record is None else np.asarray(record["survived"], dtype=bool)

    def metric(self, case: str, key: str) -> float:
        """A metric of ``case`` (NaN where missing)."""
        return float(self.data["cases"].get(case, {}).get(key, math.nan))


def rollout_size(run: Path) -> int:
    """``n_envs * n_steps`` of the run's preset (``<run>/Zerith1-v0/config.yml``); 0 if it cannot be read,
    so that only checkpoints at the very same step count as comparable."""
    path = run / ENV_ID / "config.yml"
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
        found.append(Evaluated(entry, path, data, rollout_size(entry.run)))
    return found


def comparable(first: Evaluated, second: Evaluated) -> bool:
    """Two evaluations of checkpoints at most one rollout apart, on the same robots (same settings)."""
    gap = max(first.rollout, second.rollout)
    return abs(first.steps - second.steps) <= gap and first.data["settings"] == second.data["settings"]


def method_label(method: str) -> str:
    """The paper's name of a method (``huri-baseline`` -> ``Baseline (PPO)``)."""
    return paper.LABELS.get(method, method)


def _millions(steps: int) -> str:
    """Steps in millions, as the page's labels write them."""
    return f"{steps / 1e6:.1f}M"


def _link(path: Path, page: Path) -> str:
    """``path`` relative to the page's folder (a link that works from the page)."""
    return os.path.relpath(path, page.parent)


def _figure(path: Path, page: Path, drawn: bool = True) -> list[str]:
    """The page's lines showing a figure just drawn; a figure not drawn this time is deleted, so that no
    figure outlives the data it was drawn from."""
    if not drawn:
        path.unlink(missing_ok=True)
        return []
    return [f"![{path.stem}]({_link(path, page)})", ""]


def _share(share: float, n: int) -> str:
    """A survival share with its 95% Wilson interval."""
    if n == 0 or not math.isfinite(share):
        return "-"
    low, high = wilson_interval(share, n)
    return f"{share:.2f} [{low:.2f}, {high:.2f}]"


def _difference(value: float, low: float, high: float) -> str:
    """A difference with its 95% interval, signs shown."""
    return f"{value:+.3f} [{low:+.3f}, {high:+.3f}]"


def _reading(low: float, high: float, first: str, second: str) -> str:
    """What a 95% interval of ``first - second`` says, in words."""
    if low <= 0.0 <= high:
        return "the interval includes 0: no difference measured"
    return f"{first if low > 0 else second} survives more"


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


def write_results(queue_path: Path, out: Path = Path("docs/results.md")) -> Path:
    """Write the results page ``out`` and its figures (in ``out``'s folder, under ``out``'s stem: by default
    ``docs/results/``) from the queue at ``queue_path`` and its run folders; return the page's path."""
    queue_path, out = Path(queue_path).resolve(), Path(out).resolve()
    entries = load_queue(queue_path)
    evaluations = load_evaluations(entries)
    figures = out.with_suffix("")
    figures.mkdir(parents=True, exist_ok=True)
    lines = [
        "# Results of the training campaign",
        "",
        f"Generated by `sb3_huri.experiments.results` from the queue `{_link(queue_path, out)}` and its run "
        "folders; regenerate it rather than edit it. Final evaluations: "
        f"{entries[0].defaults.eval_episodes if entries else '-'} robots per case (robot i seeded "
        f"{entries[0].defaults.eval_seed if entries else '-'} + i, the same robots for every agent), "
        "20-s episodes at 1 m/s, success = no fall.",
        "",
        *_findings_section(entries, evaluations),
        *_status_section(entries, evaluations, out),
        *_table1_section(evaluations),
        *_pairs_section(entries, evaluations),
        *_robustness_section(entries, evaluations, figures, out),
        *_returns_section(entries, figures, out),
        *_tracking_section(evaluations, figures, out),
        *_risk_section(evaluations, figures, out),
    ]
    atomic_write_text(out, "\n".join(lines) + "\n")
    return out


# --- what the numbers show ------------------------------------------------------------------------------


def pairs(evaluations: Sequence[Evaluated]) -> list[tuple[Evaluated, Evaluated]]:
    """(method, PPO) evaluations of the same protocol and seed, at most one rollout apart, on the same
    robots: every method other than the baseline against the baseline."""
    found = []
    for first in evaluations:
        if first.entry.method == BASELINE:
            continue
        for second in evaluations:
            same = (second.entry.protocol, second.entry.seed) == (first.entry.protocol, first.entry.seed)
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


def _findings_section(entries: Sequence[CampaignEntry], evaluations: Sequence[Evaluated]) -> list[str]:
    """Generated sentences: what the evaluations show, and what they cannot show yet."""
    lines = ["## What the numbers show, and what they do not", ""]
    states = {entry.name: entry.state() for entry in entries}
    done = [name for name, state in states.items() if state == "done"]
    lines.append(
        f"- {len(done)} of {len(entries)} entries evaluated" + (f": {', '.join(done)}." if done else ".")
    )
    for state, words in (("train", "still training"), ("evaluate", "trained, waiting for their evaluation")):
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
            f"- {later.entry.name} at {_millions(later.steps)} minus the same run at "
            f"{_millions(earlier.steps)} ({earlier.entry.name}), Table-1 mean on the same robots: "
            f"{_difference(mean, low, high)}: "
            + _reading(low, high, "the later checkpoint", "the earlier checkpoint")
            + "."
        )
    for (protocol, method), seeds in _seeds(evaluations).items():
        if len(seeds) < 2:
            lines.append(
                f"- {method_label(method)}, {protocol} protocol: one seed ({seeds[0]}): an anecdote, no "
                "interval over seeds yet."
            )
    return [*lines, ""]


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
        f"({_millions(first.steps)} vs {_millions(second.steps)} steps), Table-1 mean on the same robots: "
        f"{_difference(mean, low, high)}: " + _reading(low, high, name, "PPO") + "."
    )


# --- 1. status ------------------------------------------------------------------------------------------


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
    from sb3_huri.zoo.checkpoints import RunState

    run = RunState.read(entry.run)
    state = entry.state()
    if evaluated is not None:
        hours, hardware = (
            evaluated.data.get("wall_s", math.nan) / 3600,
            list(evaluated.data.get("hardware", [])),
        )
        return run.timesteps, hours, hardware, f"done (evaluated at {evaluated.steps:,})"
    cases = _evaluating(entry)
    if state == "evaluate" and cases is not None:
        state = f"evaluating ({cases} of {len(EVALUATION_CASES)} cases)"
    return run.timesteps, run.wall_s / 3600, hardware_until(entry.run, run.timesteps + 1), state


def _status_section(
    entries: Sequence[CampaignEntry], evaluations: Sequence[Evaluated], out: Path
) -> list[str]:
    """Section 1: every entry of the queue, in its order."""
    lines = [
        "## 1. Campaign status",
        "",
        "In queue order. Steps: what the run folder holds / the entry's target. Training hours and hardware: "
        "the run's sessions (`state.json`) up to the evaluated checkpoint once the entry is evaluated, up to "
        "now otherwise. A run folder may serve several entries (trained to one target, later on to another).",
        "",
        "| entry | protocol | method | seed | run | steps / target | training h | hardware | state |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    by_entry = {e.entry.name: e for e in evaluations}
    for entry in entries:
        steps, hours, hardware, state = _entry_status(entry, by_entry.get(entry.name))
        lines.append(
            f"| {entry.name} | {entry.protocol} | {method_label(entry.method)} | {entry.seed} | "
            f"`{_link(entry.run, out)}` | {steps:,} / {entry.steps:,} | "
            f"{hours:.2f} | {'; '.join(hardware) or '-'} | {state} |"
        )
    return [*lines, ""]


# --- 2. Table 1 -----------------------------------------------------------------------------------------


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


def _table1_row(evaluated: Evaluated) -> str:
    """One agent's row of the Table-1 analog: each case with its Wilson interval, the mean with its t one."""
    cells = []
    for case in SURVIVAL_CASES:
        outcomes = evaluated.survived(case)
        cells.append("-" if outcomes is None else _share(float(outcomes.mean()), outcomes.size))
    mean, low, high = table1_mean(evaluated)
    cells.insert(len(TABLE1_SCENARIOS), "-" if math.isnan(mean) else f"{mean:.3f} [{low:.3f}, {high:.3f}]")
    entry = evaluated.entry
    return f"| {entry.name} | {entry.seed} | {evaluated.steps:,} | " + " | ".join(cells) + " |"


def _seed_row(cluster: Sequence[Evaluated]) -> str:
    """Mean over seeds of one step, with the half width of its 95% t interval over the seeds."""
    cells = []
    for case in SURVIVAL_CASES:
        mean, half, n = mean_ci([e.metric(case, "survive") for e in cluster])
        cells.append(f"{mean:.3f} ± {half:.3f} ({n})" if n > 1 else "-")
    mean, half, n = mean_ci([table1_mean(e)[0] for e in cluster])
    cells.insert(len(TABLE1_SCENARIOS), f"{mean:.3f} ± {half:.3f} ({n})" if n > 1 else "-")
    seeds = ", ".join(str(seed) for seed in sorted(e.entry.seed for e in cluster))
    steps = f"~{cluster[0].steps:,}"
    return f"| **mean over seeds {seeds}** | - | {steps} | " + " | ".join(cells) + " |"


def _paper_row(method: str) -> str | None:
    """The paper's Table-1 row of ``method`` (None where the paper has none)."""
    reference = paper.TABLE1.get(method)
    if reference is None:
        return None
    cells = [f"{reference[case]:.3f}" for case in TABLE1_SCENARIOS]
    cells += [f"{np.mean(list(reference.values())):.3f}", "-"]
    return f"| *paper: {method_label(method)}* | 5 seeds | - | " + " | ".join(cells) + " |"


def _table1_section(evaluations: Sequence[Evaluated]) -> list[str]:
    """Section 2: survival per case for every evaluated agent, means over seeds, the paper's numbers."""
    lines = [
        "## 2. Survival under the paper's disturbances (Table 1 analog)",
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
        lines += [
            f"### {protocol} protocol",
            "",
            "| " + " | ".join(header) + " |",
            "|---" * len(header) + "|",
        ]
        for method in dict.fromkeys(e.entry.method for e in group):
            own = [e for e in group if e.entry.method == method]
            lines += [_table1_row(e) for e in own]
            lines += [_seed_row(cluster) for cluster in _clusters(own) if len(cluster) > 1]
            reference = _paper_row(method)
            lines += [reference] if reference else []
        lines.append("")
    return lines


# --- 2b. paired differences -----------------------------------------------------------------------------


def _pair_table(first: Evaluated, second: Evaluated, first_name: str, second_name: str) -> list[str]:
    """Per case: both shares, ``first - second`` with Newcombe's paired 95% interval, the robots only one
    of them survived; then the Table-1 mean's paired difference (t over the robots)."""
    lines = [
        f"| case | {first_name} | {second_name} | difference [95%] | only {first_name} survived | "
        f"only {second_name} survived | reading |",
        "|---|---|---|---|---|---|---|",
    ]
    for case in SURVIVAL_CASES:
        a, b = first.survived(case), second.survived(case)
        if a is None or b is None or a.shape != b.shape:
            continue
        difference, low, high = paired_difference_interval(a, b)
        reading = _reading(low, high, first_name, second_name)
        lines.append(
            f"| {case} | {a.mean():.2f} | {b.mean():.2f} | {_difference(difference, low, high)} | "
            f"{int(np.sum(a & ~b))} | {int(np.sum(~a & b))} | {reading} |"
        )
    mean, low, high = mean_difference(first, second)
    if math.isfinite(mean):
        lines.append(
            f"| Table-1 mean (t over robots) | {table1_mean(first)[0]:.3f} | {table1_mean(second)[0]:.3f} | "
            f"{_difference(mean, low, high)} | - | - | {_reading(low, high, first_name, second_name)} |"
        )
    return [*lines, ""]


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
                states = (first.state(), second.state())
                if states != ("done", "done"):
                    waiting.append(f"{first.name} ({states[0]}) with {second.name} ({states[1]})")
    return waiting


def _pairs_section(entries: Sequence[CampaignEntry], evaluations: Sequence[Evaluated]) -> list[str]:
    """Section 2's paired comparisons: HuRi minus PPO, and later minus earlier checkpoints of a run."""
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
        lines += _pair_table(first, second, name, "PPO")
    if not found:
        lines += ["No pair of a method and PPO is evaluated at comparable steps yet.", ""]
    waiting = _waiting_pairs(entries)
    if waiting:
        lines += ["Pairs still waiting: " + "; ".join(waiting) + ".", ""]
    lines += _seed_differences(found)
    for later, earlier in later_checkpoints(evaluations):
        lines += [f"**{later.label} minus {earlier.label}**: the same run trained on, on the same robots", ""]
        lines += _pair_table(later, earlier, _millions(later.steps), _millions(earlier.steps))
    return lines


def _seed_differences(found: Sequence[tuple[Evaluated, Evaluated]]) -> list[str]:
    """The Table-1 mean difference averaged over the seeds of each protocol and method, with a t interval
    over the seeds, where at least two seeds are paired at comparable steps."""
    lines = []
    groups: dict[tuple[str, str], list[tuple[Evaluated, Evaluated]]] = {}
    for first, second in found:
        groups.setdefault((first.entry.protocol, first.entry.method), []).append((first, second))
    for (protocol, method), members in groups.items():
        for cluster in _clusters([first for first, _ in members]):
            if len(cluster) < 2:
                continue
            chosen = [next(p for p in members if p[0] is first) for first in cluster]
            mean, half, n = mean_ci([mean_difference(a, b)[0] for a, b in chosen])
            lines.append(
                f"- {method_label(method)} minus PPO, {protocol} protocol, over {n} seeds at "
                f"~{cluster[0].steps:,} steps: Table-1 mean difference {mean:+.3f} ± {half:.3f} "
                "(95% t interval over the seeds): "
                + _reading(mean - half, mean + half, method_label(method), "PPO")
                + "."
            )
    return [*lines, ""] if lines else []


# --- 3. robustness during training ----------------------------------------------------------------------


def runs_of(entries: Sequence[CampaignEntry]) -> dict[Path, list[CampaignEntry]]:
    """Every run folder of the queue, once, with the entries that train it (queue order)."""
    runs: dict[Path, list[CampaignEntry]] = {}
    for entry in entries:
        runs.setdefault(entry.run, []).append(entry)
    return runs


def _run_label(run_entries: Sequence[CampaignEntry]) -> str:
    """A run's legend label: its entries, protocol, method and seed."""
    first = run_entries[0]
    names = ", ".join(entry.name for entry in run_entries)
    return f"{names} ({first.protocol}, {method_label(first.method)}, seed {first.seed})"


def _style(entry: CampaignEntry) -> dict[str, Any]:
    """Line color by method, line style by protocol."""
    color = METHOD_COLORS.get(entry.method)
    return {"linestyle": PROTOCOL_STYLES.get(entry.protocol, "-"), **({"color": color} if color else {})}


def _robustness_section(
    entries: Sequence[CampaignEntry], evaluations: Sequence[Evaluated], figures: Path, out: Path
) -> list[str]:
    """Section 3: every run's robustness learning curve, and its figure."""
    path = figures / "robustness.png"
    lines = [
        "## 3. Robustness during training",
        "",
        "`robustness.csv` of each run: the Table-1 mean of a checkpoint every ~5M steps, on fewer robots "
        "than the final evaluation and other seeds (the numbers in each row), so the curve is a trend, "
        "noisier than section 2; stars: the final evaluations' Table-1 means. Color: method; line style: "
        "protocol (robust solid, paper dashed, terrain dotted).",
        "",
        "| run | entries | rows | newest row: steps | its Table-1 mean | robots per case |",
        "|---|---|---|---|---|---|",
    ]
    curves = {}
    for run, run_entries in runs_of(entries).items():
        rows = list(read_rows(run).values())
        if not rows:
            continue
        curves[run] = rows
        last = rows[-1]
        lines.append(
            f"| `{_link(run, out)}` | {', '.join(e.name for e in run_entries)} | {len(rows)} | "
            f"{int(last['timesteps']):,} | {float(last['table1_mean']):.3f} | {last['episodes']} |"
        )
    if not curves:
        return [*lines[:4], "No run has a robustness curve yet.", "", *_figure(path, out, drawn=False)]
    _plot_robustness(path, runs_of(entries), curves, evaluations)
    return [*lines, "", *_figure(path, out)]


def _plot_robustness(
    path: Path,
    runs: dict[Path, list[CampaignEntry]],
    curves: dict[Path, list[dict[str, str]]],
    evaluations: Sequence[Evaluated],
) -> None:
    """Every run's Table-1 mean by steps, one line per run, its final evaluations as stars."""
    from matplotlib.figure import Figure

    figure = Figure(figsize=(8, 4.6), layout="constrained")
    axes = figure.add_subplot()
    for run, rows in curves.items():
        steps = np.array([int(row["timesteps"]) for row in rows]) / 1e6
        (line,) = axes.plot(
            steps,
            [float(row["table1_mean"]) for row in rows],
            lw=1.5,
            label=_run_label(runs[run]),
            **_style(runs[run][0]),
        )
        own = [e for e in evaluations if e.entry.run == run]
        axes.plot(
            [e.steps / 1e6 for e in own],
            [table1_mean(e)[0] for e in own],
            "*",
            ms=11,
            color=line.get_color(),
            markeredgecolor="black",
        )
    axes.set_xlabel("environment steps (millions)")
    axes.set_ylabel("Table-1 mean survival")
    axes.set_ylim(-0.02, 1.02)
    axes.grid(alpha=0.3)
    axes.set_title("Robustness during training (stars: final evaluations)")
    figure.legend(fontsize=7, loc="outside lower center", ncol=2)
    figure.savefig(path, dpi=FIGURE_DPI)


# --- 4. training return ---------------------------------------------------------------------------------


def smoothed_curve(run: Path, window: int = 50) -> tuple[np.ndarray, np.ndarray]:
    """The run's training return (``curve.csv``'s ``ep_return``, SB3's mean over the last 100 episodes)
    against samples, smoothed by a moving average over ``window`` rollouts."""
    from scipy.ndimage import uniform_filter1d

    rows = [row for row in read_curve(run) if math.isfinite(row["ep_return"])]
    if not rows:
        return np.empty(0), np.empty(0)
    steps = np.array([row["timesteps"] for row in rows])
    returns = np.array([row["ep_return"] for row in rows])
    return steps, uniform_filter1d(returns, size=min(window, len(returns)), mode="nearest")


def _returns_section(entries: Sequence[CampaignEntry], figures: Path, out: Path) -> list[str]:
    """Section 4: the training return of every run, and the Fig. 3 analog."""
    path = figures / "returns.png"
    lines = [
        "## 4. Training return (Fig. 3 analog)",
        "",
        "Mean training episode return (SB3's `ep_rew_mean`, our reward scale, which differs from the "
        "paper's) against samples, a moving average over 50 rollouts; one line per method and protocol, the "
        "mean over seeds where there are several, with a min-max band over the seeds (not a confidence "
        "band: with two or three seeds a 95% band would say little).",
        "",
        "| run | entries | steps | return, last tenth of its steps | paper's average return (its scale) |",
        "|---|---|---|---|---|",
    ]
    groups: dict[tuple[str, str], list[tuple[np.ndarray, np.ndarray]]] = {}
    for run, run_entries in runs_of(entries).items():
        curve = read_curve(run)
        if not curve:
            continue
        entry = run_entries[0]
        groups.setdefault((entry.protocol, entry.method), []).append(smoothed_curve(run))
        reference = paper.TRAINING_RETURN.get(entry.method)
        lines.append(
            f"| `{_link(run, out)}` | {', '.join(e.name for e in run_entries)} | "
            f"{int(curve[-1]['timesteps']):,} | {final_return(curve):.1f} | {reference or '-'} |"
        )
    if not groups:
        return [*lines[:4], "No run has a learning curve yet.", "", *_figure(path, out, drawn=False)]
    _plot_returns(path, groups)
    return [*lines, "", *_curriculum_sentences(entries, out), *_figure(path, out)]


def _curriculum_sentences(entries: Sequence[CampaignEntry], out: Path) -> list[str]:
    """Where a run's randomization curriculum (``curve.csv``'s ``scale``) grew: its return then measures a
    task that gets harder, and falls for that reason too."""
    lines = []
    for run in runs_of(entries):
        scales = [(row["timesteps"], row["scale"]) for row in read_curve(run) if math.isfinite(row["scale"])]
        if not scales or scales[0][1] >= 1.0:
            continue
        full = next((steps for steps, scale in scales if scale >= 1.0), None)
        where = f"reached full scale at {int(full):,} steps" if full else f"is at {scales[-1][1]:.2f} so far"
        lines.append(
            f"- `{_link(run, out)}`: its curriculum started the randomization and forces at scale "
            f"{scales[0][1]:.2f} and {where}; the return falls as the task grows harder, and compares "
            "across runs only at the same scale."
        )
    return [*lines, ""] if lines else []


def _plot_returns(path: Path, groups: dict[tuple[str, str], list[tuple[np.ndarray, np.ndarray]]]) -> None:
    """One panel per protocol: per method the mean smoothed return over its seeds, a min-max band where
    there are several (each seed counted up to where its run stopped)."""
    from matplotlib.figure import Figure

    protocols = [p for p in PROTOCOLS if any(key[0] == p for key in groups)]
    figure = Figure(figsize=(5 * len(protocols) + 1, 4), layout="constrained")
    panels = figure.subplots(1, len(protocols), squeeze=False, sharey=True)[0]
    for axes, protocol in zip(panels, protocols, strict=True):
        for (own, method), curves in groups.items():
            if own != protocol:
                continue
            grid = np.linspace(0, max(steps[-1] for steps, _ in curves if steps.size), 400)
            values = np.array([np.where(grid <= s[-1], np.interp(grid, s, r), np.nan) for s, r in curves])
            masked = np.ma.masked_invalid(values)  # a seed's curve ends where its run stopped
            color = METHOD_COLORS.get(method)
            label = f"{method_label(method)} ({len(curves)} seed{'s' * (len(curves) > 1)})"
            mean = masked.mean(axis=0).filled(np.nan)
            (line,) = axes.plot(grid / 1e6, mean, lw=1.5, label=label, **({"color": color} if color else {}))
            if len(curves) > 1:
                several = masked.count(axis=0) > 1
                low, high = (
                    np.where(several, bound.filled(np.nan), np.nan)
                    for bound in (masked.min(axis=0), masked.max(axis=0))
                )
                axes.fill_between(grid / 1e6, low, high, color=line.get_color(), alpha=0.2)
        axes.set_title(f"{protocol} protocol")
        axes.set_xlabel("environment steps (millions)")
        axes.grid(alpha=0.3)
        axes.legend(fontsize=8)
    panels[0].set_ylabel("training return (moving average)")
    figure.savefig(path, dpi=FIGURE_DPI)


# --- 5. velocity tracking -------------------------------------------------------------------------------


def _tracking_section(evaluations: Sequence[Evaluated], figures: Path, out: Path) -> list[str]:
    """Section 5: velocity-tracking errors and survival under load, friction and both (Fig. 4 analog)."""
    path = figures / "tracking.png"
    lines = [
        "## 5. Velocity tracking (Fig. 4 analog)",
        "",
        "Mean linear velocity error |v_xy - v_cmd| (m/s) and yaw-rate error |w_z - w_cmd| (rad/s) over the "
        "steps before a fall, command 1 m/s, a random U[0, 100] N push every 0.5 s; survival (Wilson 95%) "
        "beside them. An agent that falls early is measured on fewer, earlier steps: compare the errors of "
        "agents whose survival is alike.",
        "",
        "| agent | " + " | ".join(f"{case}: linear / yaw (survival)" for case in TRACKING_CASES) + " |",
        "|---|" + "---|" * len(TRACKING_CASES),
    ]
    shown = [e for e in evaluations if any(case in e.data["cases"] for case in TRACKING_CASES)]
    for evaluated in shown:
        cells = []
        for case in TRACKING_CASES:
            outcomes = evaluated.survived(case)
            survival = "-" if outcomes is None else _share(float(outcomes.mean()), outcomes.size)
            errors = f"{evaluated.metric(case, 'lin_err'):.3f} / {evaluated.metric(case, 'yaw_err'):.3f}"
            cells.append(f"{errors} ({survival})")
        lines.append(f"| {evaluated.label} | " + " | ".join(cells) + " |")
    if not shown:
        return [*lines[:4], "No entry is evaluated yet.", "", *_figure(path, out, drawn=False)]
    _plot_tracking(path, shown)
    return [*lines, "", *_figure(path, out)]


def _plot_tracking(path: Path, shown: Sequence[Evaluated]) -> None:
    """Bars of the linear (top) and yaw-rate (bottom) errors per case and agent, labelled with survival."""
    from matplotlib.figure import Figure

    figure = Figure(figsize=(8, 5.2), layout="constrained")
    panels = figure.subplots(2, 1, sharex=True)
    width = 0.8 / len(shown)
    x = np.arange(len(TRACKING_CASES))
    for axes, key, unit in zip(panels, ("lin_err", "yaw_err"), ("m/s", "rad/s"), strict=True):
        for index, evaluated in enumerate(shown):
            values = [evaluated.metric(case, key) for case in TRACKING_CASES]
            bars = axes.bar(x + (index - (len(shown) - 1) / 2) * width, values, width, label=evaluated.label)
            survival = [evaluated.metric(case, "survive") for case in TRACKING_CASES]
            axes.bar_label(bars, [f"{s:.2f}" for s in survival], fontsize=7, padding=1)
        axes.set_ylabel(f"{'linear' if key == 'lin_err' else 'yaw-rate'} error ({unit})")
        axes.grid(alpha=0.3, axis="y")
        axes.margins(y=0.15)
    panels[1].set_xticks(x, TRACKING_CASES)
    panels[0].set_title("Velocity tracking error (bar labels: survival)")
    panels[0].legend(fontsize=7)
    figure.savefig(path, dpi=FIGURE_DPI)


# --- 6. risk --------------------------------------------------------------------------------------------


def _risk_order(evaluated: Evaluated) -> str:
    """Whether the agent's mean IQR follows the paper's order, uneven > push > plane (Fig. 5)."""
    iqr = [evaluated.metric(case, "iqr") for case in ("uneven", PUSH_CASE, PLANE_CASE)]
    if not all(math.isfinite(value) for value in iqr):
        return "not traced"
    if max(iqr) == 0.0:
        return "IQR 0 everywhere (a scalar critic: one atom)"
    holds = iqr[0] > iqr[1] > iqr[2]
    return ("holds" if holds else "does not hold") + " (uneven > push > plane)"


def _risk_section(evaluations: Sequence[Evaluated], figures: Path, out: Path) -> list[str]:
    """Section 6: the critic's IQR and beta per agent and condition, and robot 0's traces (Fig. 5 analog)."""
    path = figures / "risk.png"
    lines = [
        "## 6. Risk along the episodes (Fig. 5 analog)",
        "",
        "The critic's interquartile range (IQR, in normalized-return units) and risk parameter beta (Wang; "
        "positive is risk-averse), means over every robot-step, on the plane (`nominal@1`), under sudden "
        "150-200 N pushes on the centroid (`sudden-centroid`) and on uneven ground. The PPO baseline's "
        "critic is scalar: its IQR and beta are 0 by construction. Figure: robot 0's critic value (the "
        "mean of its quantiles; the trace ends where the robot fell), IQR and beta along its episode, the "
        "pushes' force in grey. The value's units are each checkpoint's own reward normalization: compare "
        "its shape along the episode, not its level across agents.",
        "",
        "| agent | "
        + " | ".join(f"IQR {RISK_LABELS[c]}" for c in RISK_CASES)
        + " | "
        + " | ".join(f"beta {RISK_LABELS[c]}" for c in RISK_CASES)
        + " | paper's IQR order |",
        "|---|" + "---|" * (2 * len(RISK_CASES) + 1),
    ]
    traced = [
        e for e in evaluations if any(trace_path(e.entry.run, e.steps, c).is_file() for c in RISK_CASES)
    ]
    for evaluated in evaluations:
        cells = [f"{evaluated.metric(case, key):.3f}" for key in ("iqr", "beta") for case in RISK_CASES]
        lines.append(f"| {evaluated.label} | " + " | ".join(cells) + f" | {_risk_order(evaluated)} |")
    if not traced:
        return [*lines[:4], "No risk trace is written yet.", "", *_figure(path, out, drawn=False)]
    _plot_risk(path, traced)
    return [*lines, "", *_figure(path, out)]


RISK_ROWS = (
    ("value", "critic value (normalized return)"),
    ("iqr", "IQR (normalized return)"),
    ("beta", "beta"),
)
"""The rows of the risk figure: the critic's value (mean of its quantiles: a scalar critic's one atom), its
interquartile range and the risk parameter, along robot 0's episode."""


def _plot_risk(path: Path, traced: Sequence[Evaluated]) -> None:
    """Robot 0's critic value, IQR and beta along its episode per risk case (columns), the pushes' force in
    grey under the push's value."""
    from matplotlib.figure import Figure

    from zerith_gym.robot import CONTROL_DT

    figure = Figure(figsize=(12, 7.5), layout="constrained")
    panels = figure.subplots(len(RISK_ROWS), len(RISK_CASES), squeeze=False, sharex=True)
    for column, case in enumerate(RISK_CASES):
        files = [(e, trace_path(e.entry.run, e.steps, case)) for e in traced]
        traces = [(e, read_trace(file)) for e, file in files if file.is_file()]
        for evaluated, trace in traces:
            time_s = np.arange(len(trace["beta"])) * CONTROL_DT
            series = {"value": trace["atoms"].mean(axis=1), "iqr": trace["iqr"], "beta": trace["beta"]}
            for row, (key, _) in enumerate(RISK_ROWS):
                panels[row][column].plot(time_s, series[key], lw=1, label=evaluated.label)
        if case == PUSH_CASE and traces:  # the same robots, so the same pushes, for every agent
            force = np.nan_to_num(traces[0][1]["force"])
            force_axes = panels[0][column].twinx()
            force_axes.fill_between(np.arange(len(force)) * CONTROL_DT, 0, force, color="grey", alpha=0.25)
            force_axes.set_ylabel("force (N)")
            force_axes.set_zorder(panels[0][column].get_zorder() - 1)  # the force behind the value
            panels[0][column].patch.set_visible(False)
        for row, (key, _) in enumerate(RISK_ROWS):
            panels[row][column].set_title(f"{key}: {RISK_LABELS[case]}")
            panels[row][column].grid(alpha=0.3)
        panels[-1][column].set_xlabel("time (s)")
    for row, (_, label) in enumerate(RISK_ROWS):
        panels[row][0].set_ylabel(label)
    panels[0][0].legend(fontsize=7)
    figure.savefig(path, dpi=FIGURE_DPI)
