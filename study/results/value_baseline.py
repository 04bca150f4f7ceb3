"""The results page's value-baseline section: how good a baseline each agent's value is, and its risk level
before a fall (``study.analyses.value_baseline``), for every evaluated entry, with the file the
campaign (or ``study.scripts.value_baseline``) wrote for its evaluated checkpoint; the entries without one
are listed with the command that measures them."""

from __future__ import annotations

from collections.abc import Sequence

from sb3_huri.experiments.markdown import table
from study.analyses.value_baseline import PRE_FALL_STEPS, measured_record, value_baseline_path
from study.campaign.queue import CampaignEntry
from study.results.markdown import millions
from study.results.risk_levels import evaluated_steps, measure_command
from study.results.sections import heading, section

SCRIPT = "study/scripts/value_baseline.py"


def _range(record: dict, name: str) -> str:
    spread = [rollout[name] for rollout in record["per_rollout"]]
    return f"{record['explained_variance'][name]:.3f} [{min(spread):.2f}, {max(spread):.2f}]"


def _row(entry: CampaignEntry, steps: int, record: dict) -> list[str]:
    """One agent's row: states, both explained variances and their gap, the risk level before falls."""
    settings = record["settings"]
    states = settings["rollouts"] * settings["robots"] * settings["rollout_steps"]
    explained = record["explained_variance"]
    cells = [f"{entry.name} @ {millions(steps)}", entry.method, f"{states:,}", _range(record, "value")]
    if "atom_mean" in explained:
        cells += [_range(record, "atom_mean"), f"{explained['value'] - explained['atom_mean']:+.3f}"]
    else:
        cells += ["-", "-"]
    before, elsewhere = record["risk_before_fall"], record["risk_elsewhere"]
    cells.append("-" if before is None else f"{before:+.2f}")
    cells.append("-" if elsewhere is None else f"{elsewhere:+.2f}")
    cells.append(str(record["falls"]))
    return cells


def _measured(entries: Sequence[CampaignEntry]) -> list[tuple[CampaignEntry, int, dict]]:
    """The evaluated entries whose evaluated checkpoint's value is measured, with its steps and record."""
    found = []
    for entry in entries:
        steps = evaluated_steps(entry)
        record = None if steps is None else measured_record(value_baseline_path(entry.run, steps))
        if record is not None:
            found.append((entry, steps, record))
    return found


def value_baseline_findings(entries: Sequence[CampaignEntry]) -> list[str]:
    """The headline's line: per robot, on how many of its measured quantile-critic agents the value the
    advantages use explains less of the returns than the atoms' mean, and by how much."""
    lines = []
    for env_id in dict.fromkeys(entry.env_id for entry in entries):
        gaps = [
            record["explained_variance"]["value"] - record["explained_variance"]["atom_mean"]
            for entry, _, record in _measured(entries)
            if entry.env_id == env_id and "atom_mean" in record["explained_variance"]
        ]
        if gaps:
            below = sum(gap < 0 for gap in gaps)
            lines.append(
                f"- {env_id}: the distorted value `V_beta` explains less of the agent's training returns "
                f"than its own atoms' mean on {below} of {len(gaps)} agents with a quantile critic "
                f"(value minus atoms' mean {min(gaps):+.3f} to {max(gaps):+.3f}, "
                f"{section('value_baseline')}): "
                "one checkpoint each."
            )
    return lines


def value_baseline_section(entries: Sequence[CampaignEntry]) -> list[str]:
    """The value-baseline section: a row per evaluated agent and its measures; the agents not measured yet,
    with the command."""
    lines = [
        heading("value_baseline", "The value as a baseline, and the risk level before a fall"),
        "",
        "PPO's advantages are the return minus a baseline; HuRi's baseline is its distorted value `V_beta`, "
        "about the atoms' mean minus `beta(s)` times their spread, so its risk level moves the baseline from "
        f"state to state. On the agent's own training rollouts (as in {section('advantages')}: its preset's "
        "env at its "
        "curriculum stage, stochastic actions, one episode of warm-up, then the rollouts measured: "
        "`states`), each state's lambda = 1 return (the discounted rewards to the rollout's end, "
        "bootstrapped there and at time-outs from the same value) is explained by the value its "
        "advantages use (HuRi's `V_beta`, PPO's `V`) and, for a quantile critic, by its atoms' mean: the "
        "explained variance `1 - Var(G - V) / Var(G)` over every state measured, with its range over the "
        "rollouts. A value that explains less is a noisier baseline. Then the mean risk level (Wang "
        f"`beta`) of the states within {PRE_FALL_STEPS} steps of a fall (the fall's step included; a "
        "time-out is no fall) and of every other state: a negative level is risk-seeking, a reading of "
        "those states as safe. These describe each agent at its own step; one seed each, they do not rank "
        "methods.",
        "",
    ]
    measured = _measured(entries)
    rows = [_row(entry, steps, record) for entry, steps, record in measured]
    done = {entry.name for entry, _, _ in measured}
    missing = [
        f"{entry.name}: {measure_command(entry, SCRIPT)}"
        for entry in entries
        if evaluated_steps(entry) is not None and entry.name not in done
    ]
    if rows:
        header = ["agent", "method", "states", "explained by its value (V_beta; PPO: V) [rollouts]"]
        header += ["explained by the atoms' mean [rollouts]", "value minus atoms' mean"]
        header += ["risk level before a fall", "risk level elsewhere", "falls"]
        lines += [*table(header, rows), ""]
    else:
        lines += ["No agent's value is measured as a baseline yet.", ""]
    if missing:
        lines += ["Not measured yet: " + "; ".join(missing) + ".", ""]
    return lines
