"""A run's learning curve, ``curve.csv``: one row per rollout, written by ``CurveWriter``, read, and cut back
on resuming.

Every training of this package writes the same curve (``CurveWriter``, through
``sb3_huri.runner.checkpoint.RunCheckpoint``): steps, cumulative
training wall time, the recent episodes' mean length and return (what SB3 logs as ``ep_len_mean`` and
``ep_rew_mean``), the share of the rollout's ended episodes that fell, the curriculum's scale, and the
previous update's approximate KL, clip fraction, critic explained variance, action noise and learning rates,
and on a tile terrain the robots' mean terrain level (the paper's Figures 10 and 11). With a quantile
critic, also the rollout's risk levels in use: the shares of its states below, within and above the IQR
band, the band's thresholds, the mean risk level (Wang's ``beta``) and its RND part.
"""

from __future__ import annotations

import contextlib
import csv
import errno
import io
import math
import os
from collections.abc import Iterator, Mapping
from pathlib import Path
from typing import Any

import numpy as np
from stable_baselines3.common.callbacks import BaseCallback
from stable_baselines3.common.vec_env import VecEnv

from sb3_huri.runner.files import RunError, naming, replaced
from sb3_huri.runner.state import terrain_levels
from zerith_gym.core.infos import ended_falls

CURVE_FILE = "curve.csv"
CURVE_COLUMNS = (
    "timesteps", "wall_s", "ep_len", "ep_return", "fall_rate", "scale",
    "approx_kl", "clip_fraction", "explained_variance", "std", "learning_rate", "critic_learning_rate",
    "terrain_level",
    "iqr_below", "iqr_within", "iqr_above", "iqr_t_min", "iqr_t_max", "risk_mean", "risk_rnd_mean",
)  # fmt: skip
RISK_COLUMNS = {
    "iqr_below": "rollout/iqr_below_share",
    "iqr_within": "rollout/iqr_within_share",
    "iqr_above": "rollout/iqr_above_share",
    "iqr_t_min": "rollout/iqr_t_min",
    "iqr_t_max": "rollout/iqr_t_max",
    "risk_mean": "rollout/risk_mean",
    "risk_rnd_mean": "rollout/risk_rnd_mean",
}
"""The risk columns and the logger keys of the rollout they come from (``RiskModel.rollout_metrics``)."""
OPTIONAL_COLUMNS = ("terrain_level", *RISK_COLUMNS)
"""Columns later than the first curves: NaN in the rows written before them."""


def _cell(value: object) -> object:
    return f"{value:.6g}" if isinstance(value, float) else value


def append_row(folder: str | os.PathLike, row: Mapping[str, object]) -> None:
    """Append one rollout's row (keys: ``CURVE_COLUMNS``) to the curve of ``folder`` (the header first; a
    curve written with fewer columns gets today's header first, its rows blank in the new columns). A write
    that fails (a full disk) is cut back off the file, which keeps its rows whole, and its OSError names
    the file; RunError for a curve that does not read."""
    path = Path(folder) / CURVE_FILE
    new = not path.is_file()
    path.parent.mkdir(parents=True, exist_ok=True)
    if not new:
        with _reading(path), path.open(newline="") as file:
            header = next(csv.reader(file), [])
        if header != list(CURVE_COLUMNS):
            _rewrite(path, _rows(path))
    text = io.StringIO(newline="")
    writer = csv.DictWriter(text, fieldnames=CURVE_COLUMNS)
    if new:
        writer.writeheader()
    writer.writerow({key: _cell(value) for key, value in row.items()})
    _append(path, text.getvalue().encode())


def _append(path: Path, data: bytes) -> None:
    """`data` at the end of the file at `path` in one write; on a failure (or a short write: a full disk)
    the file is cut back to its former end, and the OSError names it."""
    descriptor = os.open(path, os.O_WRONLY | os.O_APPEND | os.O_CREAT, 0o644)
    try:
        end = os.fstat(descriptor).st_size
        try:
            if os.write(descriptor, data) < len(data):
                raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        except OSError as error:
            with contextlib.suppress(OSError):
                os.ftruncate(descriptor, end)
            raise naming(error, path) from error
    finally:
        os.close(descriptor)


@contextlib.contextmanager
def _reading(path: Path) -> Iterator[None]:
    """Reading the curve at `path`: RunError naming it if its bytes are not a CSV file's."""
    try:
        yield
    except (UnicodeDecodeError, csv.Error) as error:
        raise RunError(
            f"{path} is corrupt ({error}); it should hold a run's learning curve (move it aside to go on "
            "without its rows)"
        ) from error


def read_curve(folder: str | os.PathLike) -> list[dict[str, float]]:
    """The curve's rows as floats (NaN where a figure was not logged); a torn last line, from a kill while
    writing it, is left out."""
    path = Path(folder) / CURVE_FILE
    if not path.is_file():
        return []
    rows = []
    with _reading(path), path.open(newline="") as file:
        for row in csv.DictReader(file):
            try:
                values = {
                    key: float(row.get(key) or "nan") if key in OPTIONAL_COLUMNS else float(row[key])
                    for key in CURVE_COLUMNS
                }
            except (KeyError, TypeError, ValueError):
                continue
            if math.isfinite(values["timesteps"]):
                rows.append(values)
    return rows


def final_return(curve: list[dict[str, float]]) -> float:
    """Mean of a learning curve's ``ep_return`` over the last tenth of its steps (NaN without episodes)."""
    rows = [row for row in curve if math.isfinite(row["ep_return"])]
    if not rows:
        return math.nan
    last = rows[-1]["timesteps"]
    last_tenth = [row["ep_return"] for row in rows if row["timesteps"] >= 0.9 * last]
    return math.fsum(last_tenth) / len(last_tenth)


def wall_time_at(run: str | os.PathLike, steps: int) -> float:
    """The run's training wall time when it reached `steps` (the curve's nearest row at or before it)."""
    wall = 0.0
    path = Path(run) / CURVE_FILE
    if not path.is_file():
        return wall
    with path.open() as file:
        for row in csv.DictReader(file):
            if int(row["timesteps"]) > steps:
                break
            wall = float(row["wall_s"])
    return wall


def trim_curve(folder: str | os.PathLike, steps: int) -> None:
    """Keep the rows up to ``steps`` (a resumed run trains the steps after its checkpoint again); the file
    is replaced whole, never left torn."""
    path = Path(folder) / CURVE_FILE
    if not path.is_file():
        return
    rows = _rows(path)
    kept = [row for row in rows if row.get("timesteps", "").isdigit() and int(row["timesteps"]) <= steps]
    if len(kept) == len(rows):
        return
    _rewrite(path, kept)


def _rows(path: Path) -> list[dict[str, str]]:
    with _reading(path), path.open(newline="") as file:
        return list(csv.DictReader(file))


def _rewrite(path: Path, rows: list[dict[str, str]]) -> None:
    """Replace the curve with `rows` under today's header, whole (never left torn)."""
    text = io.StringIO()
    writer = csv.DictWriter(text, fieldnames=CURVE_COLUMNS, extrasaction="ignore")
    writer.writeheader()
    writer.writerows(rows)
    with replaced(path) as temporary:
        temporary.write_text(text.getvalue())


_TRAIN_COLUMNS = CURVE_COLUMNS[6:12]


def update_figures(model: Any) -> dict[str, float]:
    """The recent episodes' mean length and return, and the previous update's figures (SB3's logger holds
    them until the next dump, so read them at the end of a rollout; NaN where not logged)."""
    values = model.logger.name_to_value
    episodes = list(model.ep_info_buffer)
    return {
        "ep_len": float(np.mean([e["l"] for e in episodes])) if episodes else np.nan,
        "ep_return": float(np.mean([e["r"] for e in episodes])) if episodes else np.nan,
        **{key: float(values.get(f"train/{key}", np.nan)) for key in _TRAIN_COLUMNS},
    }


def risk_figures(model: Any) -> dict[str, float]:
    """The rollout's risk levels in use (``RISK_COLUMNS``), as the algorithm logged them at its end; empty
    for a scalar critic, and NaN for a figure it does not log (the RND part without RND)."""
    values = model.logger.name_to_value
    if "rollout/risk_mean" not in values:
        return {}
    return {column: float(values.get(key, np.nan)) for column, key in RISK_COLUMNS.items()}


class UpdateRecorder(BaseCallback):
    """Keeps a row per update in `rows`: steps and `update_figures` (for benchmarks comparing settings)."""

    def __init__(self) -> None:
        super().__init__()
        self.rows: list[dict[str, float]] = []

    def _on_step(self) -> bool:
        return True

    def _on_rollout_end(self) -> None:
        if "train/approx_kl" in self.model.logger.name_to_value:
            self.rows.append({"timesteps": self.num_timesteps, **update_figures(self.model)})


def _mean_level(env: VecEnv) -> float:
    """The robots' mean terrain level (tile row) now; NaN off tile terrains."""
    levels = terrain_levels(env)
    return float(np.mean(levels)) if levels else np.nan


class CurveWriter(BaseCallback):
    """After every rollout, a row of the run's learning curve in `folder`.

    When training starts, the rows past the model's step count are dropped (a resumed run trains those steps
    again). Subclasses say what the run's training wall time is (`wall_s`, all sessions).

    :param folder: where `curve.csv` is
    :param curriculum: the run's randomization curriculum (its `scale` is recorded), or None (scale 1)
    """

    def __init__(self, folder: str | os.PathLike, curriculum: Any | None = None, verbose: int = 0) -> None:
        super().__init__(verbose)
        self.folder, self.curriculum = Path(folder), curriculum
        self._episodes = self._falls = 0

    @property
    def wall_s(self) -> float:
        """Training wall time of the run so far (seconds, all sessions)."""
        raise NotImplementedError

    def _on_training_start(self) -> None:
        trim_curve(self.folder, self.num_timesteps)

    def _on_step(self) -> bool:
        falls = ended_falls(self.locals["dones"], self.locals["infos"])
        self._episodes += len(falls)
        self._falls += sum(falls)
        return True

    def _on_rollout_end(self) -> None:
        figures = update_figures(self.model)
        append_row(
            self.folder,
            {
                "timesteps": self.num_timesteps,
                "wall_s": round(self.wall_s, 1),
                "ep_len": figures.pop("ep_len"),
                "ep_return": figures.pop("ep_return"),
                "fall_rate": self._falls / self._episodes if self._episodes else np.nan,
                "scale": self.curriculum.scale if self.curriculum is not None else 1.0,
                **figures,
                "terrain_level": _mean_level(self.training_env),
                **risk_figures(self.model),
            },
        )
        self._episodes = self._falls = 0
