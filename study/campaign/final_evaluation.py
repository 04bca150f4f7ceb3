"""The final evaluation of a campaign entry: its checkpoint at the entry's step, once, under the paper's
protocol, into the run's evaluation record (``sb3_huri.runner.record``: ``<run>/evaluations/<steps>.json``).

An entry of the campaign's queue (``study.campaign.queue``) trains a run folder up to
``entry.steps``; its evaluation takes the first model the run saved at or after that step
(``find_checkpoint``: the run's newest model or a kept checkpoint) and runs every case of
``evaluation_cases`` (its robot's) on ``eval_episodes`` robots seeded ``eval_seed + i``. The record is
about the entry (its name, protocol, method and seed), so that ``CampaignEntry.evaluation`` finds it.
"""

from __future__ import annotations

from pathlib import Path

from sb3_huri.experiments.errors import ExperimentError
from sb3_huri.runner.evaluation import PROTOCOL
from sb3_huri.runner.folder import CHECKPOINTS, saved_models
from sb3_huri.runner.record import EvalSettings, evaluate_checkpoint, read_record, record_path
from study.campaign.queue import CampaignEntry

EVALUATION_CASES = (*PROTOCOL, "side-impact", "nominal@0.5")
"""The paper's protocol (Table 1, Figs. 4 and 5, the terrain tests), one 200 N push from the side, and
walking at the training speed (0.5 m/s) on the plane: the robustness curve's two extra cases."""
QUADRUPED_CASES = ("nominal@1", "nominal@0.5", "platform-0.40", "platform-0.45")
"""The quadruped's: walking at 1 and 0.5 m/s on the plane, and the paper's Table 8 (stepping down a 0.40
and a 0.45 m platform at 1 m/s under a centroid force U[0, 100] N redrawn every 2 s, +-1 kg on the trunk)."""


def evaluation_cases(entry: CampaignEntry) -> tuple[str, ...]:
    """The cases of the entry's final evaluation: its robot's."""
    return QUADRUPED_CASES if entry.protocol == "quadruped" else EVALUATION_CASES


def find_checkpoint(entry: CampaignEntry) -> tuple[int, Path, Path | None]:
    """The entry's checkpoint: the first saved model at or after ``entry.steps`` (steps, model file,
    normalizer file). ExperimentError saying what the run holds when it has none that far."""
    found = saved_models(entry.run, entry.env_id)
    later = [steps for steps in found if steps >= entry.steps]
    if not later:
        held = ", ".join(f"{steps:,}" for steps in found) or "none"
        raise ExperimentError(
            f"entry {entry.name}: run {entry.run} has no saved model at or after {entry.steps:,} steps "
            f"(models held: {held}); train it further, or keep a checkpoint of that step in "
            f"{entry.run / CHECKPOINTS}"
        )
    steps = min(later)
    return steps, *found[steps]


def evaluate_entry(
    entry: CampaignEntry, workers: int | None = 0, *, episode_steps: int | None = None
) -> Path:
    """Evaluate the entry's checkpoint (``find_checkpoint``) on every case of ``evaluation_cases``; return
    the path of its record, at once if it exists already. ExperimentError if the checkpoint's record is
    another entry's (two entries of one run need checkpoints at their own steps).

    ``workers``: processes stepping the robots (``zerith_gym.make_vec_env``; 0: all in this process, None:
    one per core). ``episode_steps``: the time limit in control steps (default the queue's).
    """
    steps, model_file, normalizer_file = find_checkpoint(entry)
    defaults = entry.defaults
    settings = EvalSettings(
        defaults.eval_episodes, defaults.eval_seed, episode_steps or defaults.episode_steps
    )
    about = {"entry": entry.name, "protocol": entry.protocol, "method": entry.method, "seed": entry.seed}
    owner = (read_record(entry.run, steps) or {}).get("entry", entry.name)
    if owner != entry.name:
        raise ExperimentError(
            f"entry {entry.name}: its checkpoint {steps} was already evaluated for entry {owner} "
            f"({record_path(entry.run, steps)}); two entries of one run need checkpoints at their own steps"
        )
    return evaluate_checkpoint(
        entry.run, steps, (model_file, normalizer_file), evaluation_cases(entry), settings, about,
        env_id=entry.env_id, workers=workers,
    )  # fmt: skip
