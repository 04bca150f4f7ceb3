"""A run's previous checkpoint beside its newest, and the fall back to it when the newest does not load.

A checkpoint is a set of files (``checkpoint_files``): the model, its normalizer, the preset and arguments,
the random states and ``state.json``, each written whole (``sb3_huri.runner.files``) in that order,
``state.json`` last: a set is complete when its ``state.json`` is there. Before a checkpoint replaces them,
``keep_previous`` puts the complete set into ``<run>/.previous/`` (hard links: no copy, and no disk space
while the newest is unchanged; git-ignored, and beside ``checkpoints/``, whose files are the kept copies),
so that:

- a save that fails (a full disk, a read-only one, an interrupt) puts the previous set back
  (``restore_previous``): the newest checkpoint stays the last good one;
- a newest set that does not load or does not agree with itself (``damage``: a torn model zip, an unreadable
  ``state.json``, normalizer or random states, a model of other steps than its state after a kill in the
  middle of a save) is moved aside to ``checkpoints/damaged-<time>/``, never deleted, and the previous set
  takes its place (``recover``, run by the trainer before it resumes), saying which steps are lost.

Run folders from before the previous set was kept have none: a newest set there that does not load is a
RunError saying so; one that loads but disagrees resumes as before, with the trainer's warning.
"""

from __future__ import annotations

import contextlib
import itertools
import json
import os
import pickle
import shutil
import time
import zipfile
from collections.abc import Callable
from pathlib import Path
from typing import Any

import yaml

from sb3_huri.runner.files import RunError, link_or_copy
from sb3_huri.runner.folder import CHECKPOINTS
from sb3_huri.runner.state import RANDOM_STATES_FILE, STATE_FILE, RunState
from zerith_gym import ZERITH1_ID

PREVIOUS = ".previous"
"""The folder, in the run folder, of the checkpoint before the newest (in the run folder's layout)."""


def checkpoint_files(env_id: str = ZERITH1_ID) -> tuple[str, ...]:
    """The files of a checkpoint, relative to the run folder, in the order they are written."""
    stats = Path(env_id)
    return (
        f"{env_id}.zip",
        *(str(stats / name) for name in ("vecnormalize.pkl", "config.yml", "args.yml", RANDOM_STATES_FILE)),
        str(stats / STATE_FILE),
    )


def previous_folder(run: str | os.PathLike) -> Path:
    """Where the run keeps the checkpoint before its newest (in the run folder's layout)."""
    return Path(run) / PREVIOUS


def keep_previous(run: str | os.PathLike, env_id: str = ZERITH1_ID) -> bool:
    """Put the run's newest checkpoint, if complete, into ``.previous/`` in place of the one
    there (``state.json`` last, so a kill midway leaves an incomplete set that is never used); True if it
    did. Called before a checkpoint replaces the newest files."""
    run = Path(run)
    if not (run / env_id / STATE_FILE).is_file():
        return False
    previous = previous_folder(run)
    shutil.rmtree(previous, ignore_errors=True)
    for name in checkpoint_files(env_id):
        if (run / name).is_file():
            link_or_copy(run / name, previous / name)
    return True


def restore_previous(run: str | os.PathLike, env_id: str = ZERITH1_ID) -> bool:
    """Put the checkpoint of ``.previous/`` back as the run's newest (its ``state.json`` removed
    first and put back last, so a kill midway leaves a set that ``recover`` falls back from again); False
    when there is no complete previous checkpoint."""
    run, previous = Path(run), previous_folder(run)
    *files, state = checkpoint_files(env_id)
    if not (previous / state).is_file():
        return False
    (run / state).unlink(missing_ok=True)
    for name in files:
        if (previous / name).is_file():
            link_or_copy(previous / name, run / name)
        else:
            (run / name).unlink(missing_ok=True)
    link_or_copy(previous / state, run / state)
    return True


def set_aside(
    run: str | os.PathLike, env_id: str = ZERITH1_ID, why: str = "damaged", move: bool = True
) -> Path:
    """Move the run's newest checkpoint files to ``checkpoints/<why>-<time>/`` (the run's layout), or with
    `move` False put them there too, leaving them in place (for another checkpoint to replace them, file by
    file, so that a kill midway never leaves the run without one); returns that folder."""
    run = Path(run)
    base = run / CHECKPOINTS / f"{why}-{time.strftime('%Y%m%d-%H%M%S')}"
    others = (base.with_name(f"{base.name}.{n}") for n in itertools.count(2))
    aside = next(folder for folder in itertools.chain([base], others) if not folder.exists())
    for name in checkpoint_files(env_id):
        if (run / name).is_file():
            (aside / name).parent.mkdir(parents=True, exist_ok=True)
            if move:
                os.replace(run / name, aside / name)
            else:
                link_or_copy(run / name, aside / name)
    return aside


def damage(run: str | os.PathLike, env_id: str = ZERITH1_ID) -> tuple[str, bool] | None:
    """What is wrong with the run's newest checkpoint, and whether it cannot be loaded at all (True) or
    only does not agree with itself (False); None for a good one, or for a run without a checkpoint."""
    run = Path(run)
    model, state = run / f"{env_id}.zip", run / env_id / STATE_FILE
    if not model.is_file() and not state.is_file():
        return None
    try:
        for name in reversed(checkpoint_files(env_id)[1:]):  # state.json first: what the campaign reads
            if (run / name).is_file():
                _load(run / name)
            elif name.endswith(("config.yml", "args.yml")):
                return f"{run / name} is missing", True
        if not model.is_file():
            return f"{model} is missing", True
        steps = model_steps(model)
    except (OSError, RunError) as error:
        return str(error), True
    if not state.is_file():
        return f"{state} is missing (a save cut short)", False
    saved = RunState.read(run, env_id).timesteps
    if saved != steps:
        return f"its model holds {steps:,} steps and its state.json {saved:,} (a save cut short)", False
    return None


def model_steps(path: Path) -> int:
    """The steps a saved model (an SB3 zip) learnt from; RunError naming the file if it is no whole model
    (every member's checksum is checked: a zip cut short or changed fails)."""
    try:
        with zipfile.ZipFile(path) as archive:
            broken = archive.testzip()
            data = json.loads(archive.read("data"))
    except (OSError, KeyError, ValueError, zipfile.BadZipFile, EOFError) as error:
        raise RunError(f"{path} is not a whole model ({type(error).__name__}: {error})") from error
    if broken is not None:
        raise RunError(f"{path} is not a whole model (its member {broken} fails its checksum)")
    steps = data.get("num_timesteps") if isinstance(data, dict) else None
    if not isinstance(steps, int):
        raise RunError(f"{path} is not a whole model (no num_timesteps in its data)")
    return steps


def _load(path: Path) -> Any:
    """Read a checkpoint file as the trainer will (RunError naming it if it does not read)."""
    try:
        if path.name == STATE_FILE:
            return RunState.read(path.parent.parent, path.parent.name)
        if path.suffix == ".yml":
            if not isinstance(loaded := yaml.safe_load(path.read_text()), dict):
                raise ValueError("not a mapping")
            return loaded
        if path.suffix == ".pt":
            import torch as th

            return th.load(path, weights_only=False)
        with path.open("rb") as file:
            return pickle.load(file)
    except RunError:
        raise
    except Exception as error:
        raise RunError(f"{path} does not read ({type(error).__name__}: {error})") from error


def recover(run: str | os.PathLike, env_id: str = ZERITH1_ID, echo: Callable[[str], Any] = print) -> None:
    """Make the run's newest checkpoint one that loads: a damaged one (``damage``) is moved aside and the
    previous checkpoint put in its place, saying which steps are lost. RunError when the newest does not
    load and there is no good previous checkpoint; a newest one that loads but disagrees, without a
    previous one, is left as it is (the trainer warns)."""
    run = Path(run)
    found = damage(run, env_id)
    if found is None:
        return
    what, unloadable = found
    previous = previous_folder(run)
    if not (previous / env_id / STATE_FILE).is_file() or damage(previous, env_id) is not None:
        if unloadable:
            raise RunError(
                f"{run}: its newest checkpoint does not load ({what}), and there is no good previous "
                f"checkpoint in {previous} to fall back to: put a good copy back (git restores a committed "
                "one), or move the run folder away to train the run anew"
            )
        return
    lost = _steps_or_none(run, env_id)
    aside = set_aside(run, env_id, move=False)
    restore_previous(run, env_id)
    steps = RunState.read(run, env_id).timesteps
    cost = f"steps {steps:,} to {lost:,} are lost" if lost and lost > steps else "the steps after it are lost"
    echo(
        f"{run}: the newest checkpoint is damaged ({what}); moved to {aside}. Resuming from the previous "
        f"checkpoint, at {steps:,} steps: {cost} and trained again"
    )


def _steps_or_none(run: Path, env_id: str) -> int | None:
    """The steps of the run's newest checkpoint: the larger of its state's and its model's that read."""
    found = []
    for steps in (lambda: RunState.read(run, env_id).timesteps, lambda: model_steps(run / f"{env_id}.zip")):
        with contextlib.suppress(RunError, OSError):
            found.append(steps())
    return max(found, default=None)
