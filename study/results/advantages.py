"""The results page's advantages section: how far each agent's risk distortion moves the advantages its actor
learns from (``study.analyses.advantages``), for every evaluated entry whose method has a
quantile critic, with the file the campaign (or ``study.scripts.advantages``) wrote for its evaluated
checkpoint. The entries without one are listed with the command that measures them, or with the reason
there is none: a run that trained on past the evaluated checkpoint no longer holds it."""

from __future__ import annotations

from collections.abc import Sequence

from sb3_huri.experiments.markdown import table
from sb3_huri.huri.methods import METHODS
from sb3_huri.runner.folder import saved_models
from study.analyses.advantages import (
    COMPARATORS,
    MEASURES,
    advantages_path,
    measured_record,
    summary,
)
from study.campaign.queue import CampaignEntry
from study.results.markdown import millions
from study.results.risk_levels import evaluated_steps, measure_command
from study.results.sections import heading

SCRIPT = "study/scripts/advantages.py"


def advantages_section(entries: Sequence[CampaignEntry]) -> list[str]:
    """The advantages section: a row per evaluated agent with a quantile critic and its measures; the agents
    not measured yet, with the command."""
    lines = [
        heading("advantages", "The risk in the learning signal: how far the distortion moves the advantages"),
        "",
        "PPO's actor follows the advantages; HuRi's differ from PPO's only through the distorted value "
        "`V_beta` its GAE bootstraps from. On the agent's own training rollouts (its preset's env at its "
        "curriculum stage, stochastic actions, about one episode of warm-up, then the rollouts measured: "
        "`states`), its advantages are held against those of the same rollouts under one risk level for "
        "every state: the neutral level (Wang `beta = 0`, the critic's mean) and the rollout's mean level "
        "(the same distortion, not adapted per state); and against its own per-state levels read the "
        'other way (`sb3_huri.common.risk_gae`; docs/huri.md, "Each step at its own level"): for an agent '
        "that trained on each value at its own state's level (`td_level` `state`, every method's), each TD "
        "error at the level of the state its step starts from (`step`), and the reverse. Against each: the "
        "correlation (dominated by the "
        "largest advantages), the share of advantages whose sign changes (dominated by the many small "
        "ones) and that share weighted by the advantage's size; means over the rollouts measured "
        f"(`{SCRIPT}` prints their ranges). The same learning signal would give 1 / 0 / 0. These describe "
        "each agent at its own step and curriculum stage; they do not rank methods.",
        "",
    ]
    rows, missing = [], []
    for entry in entries:
        preset = METHODS.get(entry.method)
        steps = evaluated_steps(entry)
        if preset is None or not preset.distributional or steps is None:
            continue
        record = measured_record(advantages_path(entry.run, steps), shown=True)
        if record is None:
            held = steps in saved_models(entry.run, entry.env_id)
            how = measure_command(entry, SCRIPT) if held else "its run no longer holds that checkpoint"
            missing.append(f"{entry.name}: {how}")
            continue
        means, settings = summary(record), record["settings"]
        states = settings["rollouts"] * settings["robots"] * settings["rollout_steps"]
        curriculum = record.get("curriculum")
        cells = [f"{entry.name} @ {millions(steps)}", entry.method, f"{states:,}"]
        cells.append("-" if curriculum is None else f"{curriculum['scale']:g}")
        cells.append(f"{means['risk_mean']:+.2f} ({means['risk_sd']:.2f})")
        for name in COMPARATORS:
            measured = f"{name}_{MEASURES[0]}" in means
            cells.append(" / ".join(f"{means[f'{name}_{key}']:.3f}" for key in MEASURES) if measured else "-")
        if "other_td_level_neutral_weighted_sign_changes" in means:
            cells[-1] += f" ({means['other_td_level_neutral_weighted_sign_changes']:.3f})"
        rows.append(cells)
    if rows:
        measures = "correlation / sign changes / weighted"
        header = ["agent", "method", "states", "curriculum scale", "risk level: mean (sd over states)"]
        header += [f"against the neutral level: {measures}", f"against the rollout's mean level: {measures}"]
        header.append(
            f"against its levels read the other way: {measures} (that reading against the neutral level: "
            "weighted)"
        )
        lines += [*table(header, rows), ""]
    else:
        lines += ["No agent's advantages are measured yet.", ""]
    if missing:
        lines += ["Not measured yet: " + "; ".join(missing) + ".", ""]
    return lines
