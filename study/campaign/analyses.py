"""What a campaign entry is measured on after its final evaluation, at the evaluated checkpoint, so that
the results page's risk-levels, advantages and force-magnitude sections fill in as entries finish
(``defaults.analyses`` names them):

- ``risk_levels``: the risk levels its critic sets per scenario (``analyses.risk_levels``), for an entry
  whose method has a quantile critic;
- ``force_magnitude``: its survival over the force's magnitude, 0.1x to 1.5x of the paper's, under both
  readings of the forces on hands and feet and both hold times of a push, and on the nominal robot at the
  paper's magnitude (``analyses.force_magnitude``), for a Zerith-1 entry;
- ``advantages``: how far its risk distortion moves the advantages of its own training rollouts from those
  of a neutral and of a constant risk level (``analyses.advantages``), for a method with a quantile critic;
- ``value_baseline``: how much of its training rollouts' returns the value its advantages use explains
  (and, for a quantile critic, its atoms' mean), and its risk level before a fall
  (``analyses.value_baseline``), for every agent.

Each file is written after every case, so a measurement stopped by the wall time or a signal goes on where
it stopped. The campaign measures an entry while its run holds the evaluated checkpoint (the newest model or
a kept checkpoint); for a run trained on since, ``study.scripts.force_magnitude`` finds the model in git.
"""

from __future__ import annotations

import time
from pathlib import Path

from sb3_huri.experiments.errors import ExperimentError
from sb3_huri.huri.methods import METHODS
from sb3_huri.runner.evaluation import TABLE1_SCENARIOS
from sb3_huri.runner.files import RunError, read_json
from sb3_huri.runner.folder import saved_models
from study.analyses import advantages, force_magnitude, risk_levels, value_baseline
from study.campaign.queue import CampaignEntry
from zerith_gym import ZERITH1_ID, robot_of

FORCE_PLAN = (
    (force_magnitude.READINGS, force_magnitude.CASES, force_magnitude.SCALES),
    (force_magnitude.NOMINAL_READINGS, TABLE1_SCENARIOS, (force_magnitude.PAPER_SCALE,)),
)
"""(readings, cases, scales) of an entry's force-magnitude file: every reading at every scale, then the
nominal robot at the paper's magnitude, the headline reading first."""


def applies(name: str, entry: CampaignEntry) -> bool:
    """Whether the analysis ``name`` measures anything of the entry's agent: the risk levels of a method that
    reads the IQR band of a quantile critic, the advantages of a method with a quantile critic, the force
    magnitude of a Zerith-1 agent, the value baseline of every agent."""
    preset = METHODS.get(entry.method)
    if name == "risk_levels":
        return preset is not None and preset.distributional and preset.use_iqr
    if name == "advantages":
        return preset is not None and preset.distributional
    if name == "value_baseline":
        return True
    return entry.env_id == ZERITH1_ID


def pending(entry: CampaignEntry) -> list[str]:
    """The entry's analyses not complete yet that the campaign can measure: none before its final evaluation,
    nor once its run no longer holds the evaluated checkpoint."""
    evaluation = entry.evaluation()
    if evaluation is None:
        return []
    steps = int(evaluation.stem)
    if steps not in saved_models(entry.run, entry.env_id):
        return []
    return [
        name for name in entry.defaults.analyses if applies(name, entry) and not _complete(name, entry, steps)
    ]


def measure(entry: CampaignEntry, deadline: float | None = None) -> list[str]:
    """Measure the entry's pending analyses, starting nothing after ``deadline`` (``time.time()``); return
    the analyses still pending afterwards. One that fails leaves the others to run, then ExperimentError
    says why."""
    names = pending(entry)
    if not names:
        return []
    steps = int(entry.evaluation().stem)  # type: ignore[union-attr]
    limit = entry.defaults.episode_steps
    failed = []
    for name in names:
        try:
            if name == "risk_levels":
                risk_levels.measure_risk_levels(
                    entry.run, steps=steps, episode_steps=limit, deadline=deadline
                )
                continue
            if name == "advantages":
                if deadline is None or time.time() < deadline:
                    advantages.measure_advantages(entry.run, steps=steps)
                continue
            if name == "value_baseline":
                if deadline is None or time.time() < deadline:
                    value_baseline.measure_value_baseline(entry.run, steps=steps)
                continue
            for readings, cases, scales in FORCE_PLAN:
                force_magnitude.measure_agent(
                    entry.run, steps, readings, cases=cases, scales=scales, episode_steps=limit,
                    deadline=deadline,
                )  # fmt: skip
        except RunError as error:
            failed.append(f"{name}: {error}")
    if failed:
        raise ExperimentError(f"entry {entry.name}: " + "; ".join(failed))
    return pending(entry)


def _complete(name: str, entry: CampaignEntry, steps: int) -> bool:
    """Whether the analysis's file of the checkpoint at ``steps`` holds every case it measures."""
    if name == "advantages":
        return advantages.measured_record(advantages.advantages_path(entry.run, steps)) is not None
    if name == "value_baseline":
        path = value_baseline.value_baseline_path(entry.run, steps)
        return value_baseline.measured_record(path) is not None
    if name == "risk_levels":
        path = risk_levels.risk_levels_path(entry.run, steps)
        if not path.is_file():
            return False
        scenario = risk_levels.training_scenario(entry.run, entry.env_id)
        wanted = risk_levels.default_cases(robot_of(entry.env_id), scenario)
        return set(wanted) <= risk_levels.measured_cases(_read(path))
    path = force_magnitude.result_path(entry.run, steps)
    if not path.is_file():
        return False
    record = _read(path)
    return not any(force_magnitude.missing(record, *part) for part in FORCE_PLAN)


def _read(path: Path) -> dict:
    return read_json(path, "an analysis of a campaign entry")
