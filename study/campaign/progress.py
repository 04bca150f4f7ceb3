"""Where a campaign entry stands, and the stretch of work that moves it on.

An entry is ``new`` or ``train`` until its run holds its steps, then ``evaluate`` until its final evaluation
is written (``final_evaluation``), then ``measure`` until the queue's analyses hold every case beside it
(``analyses``), then ``done``; ``damaged`` while a file of its run does not read. ``run_entry`` takes an
entry as far as it can in one process (the campaign's child, ``child.run_child``): trained up to its steps
(resuming its run), evaluated, measured.
"""

from __future__ import annotations

import time

from sb3_huri.runner.files import RunError
from sb3_huri.runner.lock import hold_run
from study.campaign import analyses
from study.campaign.final_evaluation import evaluate_entry
from study.campaign.queue import CampaignEntry
from zerith_gym import ZERITH1_ID

CHECKPOINT_FREQ = 1_000_000
"""Env steps between an entry's checkpoints."""


def state(entry: CampaignEntry) -> str:
    """``done``, ``measure`` (evaluated, its analyses not complete), ``evaluate`` (trained, not yet
    evaluated), ``train`` (more steps to go), ``new``, or ``damaged``: a file of its run does not read
    (``problem`` says which; its trainer falls back to the previous checkpoint where it can, and the
    campaign leaves the entry alone where it cannot, the other entries going on)."""
    try:
        return checked_state(entry)
    except RunError:
        return "damaged"


def problem(entry: CampaignEntry) -> str | None:
    """Why the entry's state is ``damaged`` (a file of its run that does not read), or None."""
    try:
        checked_state(entry)
    except RunError as error:
        return str(error)
    return None


def checked_state(entry: CampaignEntry) -> str:
    """``state``, or the RunError of a file of its run that does not read."""
    steps = entry.trained_steps()
    if steps < entry.steps:
        return "train" if steps else "new"
    if entry.evaluation() is None:
        return "evaluate"
    return "measure" if analyses.pending(entry) else "done"


def run_entry(entry: CampaignEntry, max_wall_s: float | None = None, workers: int | None = None) -> str:
    """Train `entry` up to its steps (resuming its run), evaluate it, then measure its analyses
    (``campaign.analyses``); returns its state afterwards.

    The run folder is held throughout (``hold_run``), and a damaged newest checkpoint replaced by the
    previous one first (``sb3_huri.runner.fallback.recover``). A training stopped early (wall time,
    SIGTERM) leaves the entry at ``train``, to be continued; analyses cut by the wall time leave it at
    ``measure``. RunError for a file of the run that does not read."""
    from sb3_huri.runner.fallback import recover

    with hold_run(entry.run):
        recover(entry.run, entry.env_id, echo=lambda line: print(line, flush=True))
        return _run_held_entry(entry, max_wall_s, workers)


def _run_held_entry(entry: CampaignEntry, max_wall_s: float | None, workers: int | None) -> str:
    """``run_entry`` in the run folder it holds."""
    from sb3_huri.runner.training import RobustnessSchedule, RunRequest, TrainingOptions, train_run
    from sb3_huri.zoo import read_preset

    deadline = None if max_wall_s is None else time.time() + max_wall_s
    if checked_state(entry) in ("new", "train"):
        defaults = entry.defaults
        request = RunRequest(
            run=entry.run, preset=read_preset(entry.env_id, entry.conf), method=entry.method,
            seed=entry.seed, until=entry.steps, env_id=entry.env_id, hyperparams=entry.hyperparams,
        )  # fmt: skip
        rows = RobustnessSchedule(
            defaults.robustness_every,
            defaults.robustness_episodes,
            defaults.robustness_seed,
            defaults.episode_steps,
        )
        options = TrainingOptions(
            checkpoint_freq=CHECKPOINT_FREQ,
            robustness=rows if entry.env_id == ZERITH1_ID else None,  # rows are Zerith-1's Table 1
            max_wall_s=max_wall_s, workers=workers,
        )  # fmt: skip
        train_run(request, options)
    if checked_state(entry) == "evaluate":
        evaluate_entry(entry, workers=workers, episode_steps=entry.defaults.episode_steps)
    if checked_state(entry) == "measure":
        analyses.measure(entry, deadline)
    return checked_state(entry)
