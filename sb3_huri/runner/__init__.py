"""The runner: one place that trains, checkpoints, resumes, evaluates and loads a run folder.

A run folder is in RL Zoo's layout, so that ``rl_zoo3 enjoy`` and RL Zoo's plots read it, with what a run
spanning many sessions needs beside it::

    <run>/<env_id>.zip                        the newest checkpoint's model
    <run>/<env_id>/config.yml, args.yml       the preset and the run's arguments (method, seed, env options)
    <run>/<env_id>/vecnormalize.pkl           its observation normalizer
    <run>/<env_id>/state.json, rng.pt         steps, curriculum stage, terrain levels, sessions; random states
    <run>/curve.csv                           a row per rollout
    <run>/robustness.csv                      Table-1 survival every few million steps
    <run>/checkpoints/rl_model_<steps>_steps.zip, rl_model_vecnormalize_<steps>_steps.pkl   kept copies
    <run>/.previous/                          the checkpoint before the newest, to fall back to
    <run>/evaluations/<steps>.json            the evaluation record of a checkpoint
    <run>/.lock                               held by the one process writing the folder (its pid)

Its modules, each with one job:

- ``training``: ``train_run``, the one trainer of every run (new or resumed), what the grid, the campaign
  and ``examples/train_zerith.py`` call;
- ``build``: the preset's batched env, normalizer and model (what ``rl_zoo3 train`` builds);
- ``checkpoint``: ``RunCheckpoint``, the callback that checkpoints between rollouts and stops cleanly;
- ``state``: ``state.json`` and ``rng.pt``; ``curve``: ``curve.csv``; ``folder``: the folder's model files,
  saved and loaded; ``files``: writes a kill cannot tear, and ``RunError``;
- ``lock``: one writer per run folder, and trainers that end with the process that started them;
  ``fallback``: the previous checkpoint kept beside the newest, and the fall back to it;
- ``evaluation``: the paper's protocol on a trained agent; ``robustness``: ``robustness.csv``;
  ``record``: a checkpoint's evaluation record.
"""

from sb3_huri.runner.files import RunError
from sb3_huri.runner.folder import (
    copy_agent,
    load_checkpoint,
    load_model,
    load_run,
    next_run_folder,
    save_run,
)
from sb3_huri.runner.training import RobustnessSchedule, RunRequest, TrainingOptions, train_run

__all__ = [
    "RobustnessSchedule",
    "RunError",
    "RunRequest",
    "TrainingOptions",
    "copy_agent",
    "load_checkpoint",
    "load_model",
    "load_run",
    "next_run_folder",
    "save_run",
    "train_run",
]
