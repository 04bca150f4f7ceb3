"""Section 6c of the results page: how far each agent's risk distortion moves the advantages its actor
learns from (``sb3_huri.experiments.analyses.advantages``), for every evaluated entry whose method has a
quantile critic, with the file the campaign (or ``benchmarks/advantages.py``) wrote for its evaluated
checkpoint. The entries without one are listed with the command that measures them, or with the reason
there is none: a run that trained on past the evaluated checkpoint no longer holds it."""

from __future__ import annotations

from collections.abc import Sequence

from sb3_huri.experiments.analyses.advantages import advantages_path, summary
from sb3_huri.experiments.campaign.queue import CampaignEntry
from sb3_huri.experiments.campaign.results.markdown import millions
from sb3_huri.experiments.campaign.results.risk_levels import evaluated_steps, measure_command
from sb3_huri.huri.methods import METHODS
from sb3_huri.runner.files import read_json
from sb3_huri.runner.folder import saved_models

SCRIPT = "benchmarks/advantages.py"


def advantages_section(entries: Sequence[CampaignEntry]) -> list[str]:
    """Section 6c: a row per evaluated agent with a quantile critic and its measures; the agents not
    measured yet, with the command."""
    lines = [
        "## 6c. The risk in the learning signal: how far the distortion moves the advantages",
        "",
        "PPO's actor follows the advantages; HuRi's differ from PPO's only through the distorted value "
        "`V_beta` its GAE bootstraps from. On the agent's own training rollouts (its preset's env at its "
        "curriculum stage, stochastic actions, one warm-up rollout, then the means over two rollouts of "
        "16,384 states), its advantages are held against those of the same rollouts under one risk level "
        "for every state: the neutral level (Wang `beta = 0`, the critic's mean) and the rollout's mean "
        "level (the same distortion, not adapted per state). Correlation 1, no sign changes and a gap of 0 "
        "(the standard deviation of the difference of the two standardized advantages, as the actor "
        "normalizes them) would mean the same learning signal; unrelated advantages give a gap of 1.41.",
        "",
    ]
    rows, missing = [], []
    for entry in entries:
        preset = METHODS.get(entry.method)
        steps = evaluated_steps(entry)
        if preset is None or not preset.distributional or steps is None:
            continue
        path = advantages_path(entry.run, steps)
        if not path.is_file():
            held = steps in saved_models(entry.run, entry.env_id)
            how = measure_command(entry, SCRIPT) if held else "its run no longer holds that checkpoint"
            missing.append(f"{entry.name}: {how}")
            continue
        means = summary(read_json(path, "an agent's advantage measures"))
        cells = [f"{means['risk_mean']:+.2f} ({means['risk_sd']:.2f})"]
        for name in ("neutral", "constant"):
            cells.append(
                f"{means[f'{name}_correlation']:.3f} / {means[f'{name}_sign_changes']:.3f} / "
                f"{means[f'{name}_standardized_gap']:.3f}"
            )
        rows.append(f"| {entry.name} @ {millions(steps)} | {entry.method} | " + " | ".join(cells) + " |")
    if rows:
        lines += [
            "| agent | method | risk level: mean (sd over states) | against the neutral level: "
            "correlation / sign changes / gap | against the rollout's mean level: correlation / sign "
            "changes / gap |",
            "|---|---|---|---|---|",
            *rows,
            "",
        ]
    else:
        lines += ["No agent's advantages are measured yet.", ""]
    if missing:
        lines += ["Not measured yet: " + "; ".join(missing) + ".", ""]
    return lines
