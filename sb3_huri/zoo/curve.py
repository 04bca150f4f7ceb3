"""A run's learning curve, ``curve.csv``: one row per rollout, appended, read, and cut back on resuming.

Every training of this package writes the same curve (``sb3_huri.experiments.trainer``, through
``sb3_huri.zoo.checkpoints.RunCheckpoint``): steps, cumulative
training wall time, the recent episodes' mean length and return (what SB3 logs as ``ep_len_mean`` and
``ep_rew_mean``), the share of the rollout's ended episodes that fell, the curriculum's scale, and the
previous update's approximate KL, clip fraction, critic explained variance, action noise and learning rates,
and on a tile terrain the robots' mean terrain level (the paper's Figures 10 and 11). With a quantile
critic, also the rollout's risk levels in use: the shares of its states below, within and above the IQR
band, the band's thresholds, the mean risk level (Wang's ``beta``) and its RND part.
"""

from __future__ import annotations

import csv
import io
import math
import os
from collections.abc import Mapping
from pathlib import Path

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
    curve written with fewer columns gets today's header first, its rows blank in the new columns)."""
    path = Path(folder) / CURVE_FILE
    new = not path.is_file()
    path.parent.mkdir(parents=True, exist_ok=True)
    if not new:
        with path.open(newline="") as file:
            header = next(csv.reader(file), [])
        if header != list(CURVE_COLUMNS):
            _rewrite(path, _rows(path))
    with path.open("a", newline="") as file:
        writer = csv.DictWriter(file, fieldnames=CURVE_COLUMNS)
        if new:
            writer.writeheader()
        writer.writerow({key: _cell(value) for key, value in row.items()})


def read_curve(folder: str | os.PathLike) -> list[dict[str, float]]:
    """The curve's rows as floats (NaN where a figure was not logged); a torn last line, from a kill while
    writing it, is left out."""
    path = Path(folder) / CURVE_FILE
    if not path.is_file():
        return []
    rows = []
    with path.open(newline="") as file:
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
    with path.open(newline="") as file:
        return list(csv.DictReader(file))


def _rewrite(path: Path, rows: list[dict[str, str]]) -> None:
    """Replace the curve with `rows` under today's header, whole (never left torn)."""
    text = io.StringIO()
    writer = csv.DictWriter(text, fieldnames=CURVE_COLUMNS, extrasaction="ignore")
    writer.writeheader()
    writer.writerows(rows)
    temporary = path.with_name(f".{path.name}.tmp")
    temporary.write_text(text.getvalue())
    os.replace(temporary, path)
