"""A run folder's files while it trains: checkpoints, the learning curve, and writing them safely.

Kept apart from ``training`` (which imports torch and SB3 when it trains) so that reading them (the
report) imports neither.
"""

from __future__ import annotations

import csv
import io
import os
from collections.abc import Callable
from pathlib import Path

from sb3_huri.experiments.layout import atomic_write_text

CURVE_FILE = "curve.csv"
CURVE_COLUMNS = ("timesteps", "ep_rew_mean", "ep_len_mean", "seconds")
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


def read_curve(folder: Path) -> list[dict[str, float]]:
    """The rows of a run's ``curve.csv`` (a torn last line, from a kill while writing it, is left out)."""
    path = folder / CURVE_FILE
    if not path.exists():
        return []
    rows = []
    with open(path, newline="") as f:
        for row in csv.DictReader(f):
            try:
                rows.append({key: float(row[key]) for key in CURVE_COLUMNS})
            except (KeyError, TypeError, ValueError):
                continue
    return rows


def trim_curve(folder: Path, steps: int) -> None:
    """Keep the curve's rows up to ``steps`` (those after a checkpoint are trained again on resuming)."""
    kept = [row for row in read_curve(folder) if row["timesteps"] <= steps]
    text = io.StringIO()
    writer = csv.DictWriter(text, CURVE_COLUMNS, lineterminator="\n")
    writer.writeheader()
    for row in kept:
        values = {key: repr(value) for key, value in row.items()}
        writer.writerow({**values, "timesteps": int(row["timesteps"])})
    atomic_write_text(folder / CURVE_FILE, text.getvalue())


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
