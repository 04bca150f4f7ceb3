"""A run folder's checkpoints while it trains, and writing them safely (its learning curve is
``sb3_huri.zoo.curve``, shared with every training of the package)."""

from __future__ import annotations

import os
from collections.abc import Callable
from pathlib import Path

CHECKPOINTS = "checkpoints"
KEEP_CHECKPOINTS = 2


def checkpoint_paths(folder: Path, steps: int) -> tuple[Path, Path]:
    """The model and normalizer files of the checkpoint after ``steps`` steps."""
    base = folder / CHECKPOINTS
    return base / f"model_{steps}.zip", base / f"vecnormalize_{steps}.pkl"


def replace_file(write: Callable[[str], None], path: Path) -> None:
    """Write a file through ``write(temporary_path)`` and rename it to ``path`` (never a torn file)."""
    temporary = path.with_name(f".{path.name}.tmp")
    write(str(temporary))
    os.replace(temporary, path)


def prune_checkpoints(folder: Path, keep: int) -> None:
    """Delete all but the ``KEEP_CHECKPOINTS`` newest checkpoints (``keep`` steps is the newest).

    Steps are gathered from models and normalizers alike, so a half-deleted checkpoint (a kill between
    its two files) is finished off by the next prune instead of being left behind; so are the temporary
    files of a save that a kill interrupted (the run's only writer is the caller, which is not saving now).
    """
    for stale in (folder / CHECKPOINTS).glob(".*.tmp"):
        stale.unlink(missing_ok=True)
    steps = sorted(
        {
            int(path.stem.split("_")[1])
            for pattern in ("model_*.zip", "vecnormalize_*.pkl")
            for path in (folder / CHECKPOINTS).glob(pattern)
            if path.stem.split("_")[1].isdigit()
        }
    )
    for old in steps[:-KEEP_CHECKPOINTS]:
        if old != keep:
            for path in checkpoint_paths(folder, old):
                path.unlink(missing_ok=True)
