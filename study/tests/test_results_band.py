"""The results page's section on the IQR band in training (``results.band``), built from synthetic run
folders whose numbers are checked against averages computed here."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import yaml

from sb3_huri.runner.curve import CURVE_COLUMNS, append_row
from study.campaign.queue import load_queue
from study.results.band import band_section
from study.results.early_signal import early_signal_lines

STEP = 100_000


def _run(
    folder: Path, steps: int, ret: float, risk: dict[str, float] | None, table1: dict[int, float]
) -> None:
    """A run folder's curve (return rising by 1 per rollout from `ret`; with `risk`, its risk columns) and
    robustness rows."""
    for index, step in enumerate(range(STEP, steps + 1, STEP)):
        row = {**dict.fromkeys(CURVE_COLUMNS, math.nan), "timesteps": step, "wall_s": 1.0}
        row.update(ep_return=ret + index, ep_len=500.0, fall_rate=0.25)
        append_row(folder, {**row, **(risk or {})})
    lines = ["timesteps,table1_mean,episodes"] + [f"{s},{v},50" for s, v in table1.items()]
    (folder / "robustness.csv").write_text("\n".join(lines) + "\n")


def _queue(root: Path) -> Path:
    (root / "preset.yml").write_text(yaml.safe_dump({"Zerith1-v0": {"n_envs": 4}}))
    entry = dict(protocol="robust", seed=0, conf="preset.yml", steps=3_000_000)
    entries = [
        {**entry, "name": "pct", "method": "huri-percentile", "run": "pct/Zerith1-v0_1"},
        {**entry, "name": "huri", "method": "huri", "run": "huri/Zerith1-v0_1"},
        {**entry, "name": "ppo", "method": "huri-baseline", "run": "ppo/Zerith1-v0_1"},
        {**entry, "name": "other-seed", "method": "huri", "run": "huri/Zerith1-v0_2", "seed": 1},
    ]
    path = root / "campaign.yml"
    path.write_text(yaml.safe_dump({"entries": entries}))
    return path


def test_the_band_section_holds_the_percentile_run_against_literal_huri_and_ppo_at_equal_steps(tmp_path):
    band = dict(iqr_below=0.3, iqr_within=0.45, iqr_above=0.25, iqr_t_min=0.2, iqr_t_max=0.3, risk_mean=0.1)
    _run(tmp_path / "pct/Zerith1-v0_1", 2_000_000, 100.0, {**band, "risk_rnd_mean": 0.15}, {1_000_448: 0.5})
    literal = dict(band, iqr_below=0.9, iqr_within=0.1, iqr_above=0.0, iqr_t_min=0.3, iqr_t_max=0.7)
    _run(tmp_path / "huri/Zerith1-v0_1", 3_000_000, 200.0, literal, {999_936: 0.25, 2_000_000: 0.75})
    _run(tmp_path / "ppo/Zerith1-v0_1", 3_000_000, 300.0, None, {1_700_000: 0.125})
    _run(tmp_path / "huri/Zerith1-v0_2", 3_000_000, 0.0, None, {1_000_000: 0.0})
    entries = load_queue(_queue(tmp_path))
    page = tmp_path / "docs" / "results.md"
    (tmp_path / "docs" / "results").mkdir(parents=True)
    lines = band_section(entries, tmp_path / "docs" / "results", page) + early_signal_lines(entries, page)
    text = "\n".join(lines)

    # Every run that logged its risk levels gets a row (the PPO run and the other seed logged none).
    rows = {line.split(" | ")[0]: line.split(" | ") for line in lines if line.startswith("| `")}
    assert set(rows) == {"| `../pct/Zerith1-v0_1` (huri-percentile)", "| `../huri/Zerith1-v0_1` (HuRi)"}
    percentile = rows["| `../pct/Zerith1-v0_1` (huri-percentile)"]
    assert percentile[1:6] == [
        "2,000,000",
        "0.30 / 0.45 / 0.25",
        "0.30 / 0.45 / 0.25",
        "(0.200, 0.300)",
        "+0.10",
    ]
    assert rows["| `../huri/Zerith1-v0_1` (HuRi)"][2] == "0.90 / 0.10 / 0.00"

    # At 1M: the return averaged over the rollouts of (0, 1M] of each run, its own seed's peers only.
    expected = [np.mean([start + i for i in range(10)]) for start in (100.0, 200.0, 300.0)]
    row = next(line for line in lines if line.startswith("| 1M |")).split(" | ")
    assert row[1] == " / ".join(f"{value:.0f}" for value in expected)
    assert row[4] == "0.500 / 0.250 / 0.125 (1.7M)"  # the rows nearest 1M, with their step if not at it
    assert row[5].rstrip(" |") == "0.30 / 0.45 / 0.25"
    assert "| 2M |" not in text  # compared where the percentile run has a robustness row
    assert "`../huri/Zerith1-v0_2`" not in text
    assert (tmp_path / "docs" / "results" / "band.png").is_file()


def test_the_band_section_says_so_when_no_run_logged_its_risk_levels(tmp_path):
    _run(tmp_path / "ppo/Zerith1-v0_1", 1_000_000, 0.0, None, {})
    queue = _queue(tmp_path)
    figure = tmp_path / "band.png"
    figure.write_bytes(b"old")
    lines = band_section(load_queue(queue), tmp_path, tmp_path / "results.md")
    assert "No run has logged its risk levels yet." in lines and not figure.exists()


def test_the_quadruped_early_signal_shows_the_terrain_level_every_5m_steps(tmp_path):
    """Without robustness rows (the quadruped's robustness is its final platforms), the percentile run is
    compared every 5M steps of its curve, with the robots' mean terrain level in place of Table 1."""
    for run, ret, level in (("pct", 10.0, 0.5), ("huri", 20.0, 0.25), ("ppo", 30.0, 0.125)):
        folder = tmp_path / run / "Go2Like-v0_1"
        for index, step in enumerate(range(STEP, 5_000_000 + 1, STEP)):
            row = {**dict.fromkeys(CURVE_COLUMNS, math.nan), "timesteps": step, "wall_s": 1.0}
            row.update(ep_return=ret, ep_len=100.0, fall_rate=0.5, terrain_level=level + index / 100)
            append_row(folder, row)
    (tmp_path / "preset.yml").write_text(yaml.safe_dump({"Go2Like-v0": {"n_envs": 4}}))
    entry = dict(protocol="quadruped", seed=0, conf="preset.yml", steps=75_000_000)
    queue = [
        {**entry, "name": name, "method": method, "run": f"{name}/Go2Like-v0_1"}
        for name, method in (("pct", "huri-percentile"), ("huri", "huri"), ("ppo", "huri-baseline"))
    ]
    (tmp_path / "campaign.yml").write_text(yaml.safe_dump({"entries": queue}))
    lines = early_signal_lines(load_queue(tmp_path / "campaign.yml"), tmp_path / "results.md")

    header = next(line for line in lines if line.startswith("| steps |"))
    assert "terrain level" in header and "Table-1" not in header
    rows = [line.split(" | ") for line in lines if line.startswith("| ") and line[2].isdigit()]
    assert [row[0] for row in rows] == ["| 5M"]  # every 5M steps of the curve, up to its newest row
    # The window (4M, 5M] holds rollouts 40-49: the level rises by 0.01 per rollout from each run's start.
    expected = [np.mean([start + index / 100 for index in range(40, 50)]) for start in (0.5, 0.25, 0.125)]
    assert rows[0][1:5] == [
        "10 / 20 / 30",
        "100 / 100 / 100",
        "0.50 / 0.50 / 0.50",
        " / ".join(f"{value:.2f}" for value in expected),
    ]


def test_a_risk_neutral_run_is_held_against_huri_and_ppo_at_equal_steps_without_band_shares(tmp_path):
    """huri-neutral reads no IQR band: its early signal has the training figures and the Table-1 means of
    the three runs at its own robustness rows, and no band column."""
    _run(tmp_path / "neutral/Zerith1-v0_1", 2_000_000, 50.0, None, {1_000_000: 0.375, 2_000_000: 0.5})
    _run(tmp_path / "huri/Zerith1-v0_1", 3_000_000, 200.0, None, {2_000_000: 0.25})
    _run(tmp_path / "ppo/Zerith1-v0_1", 3_000_000, 300.0, None, {999_000: 0.125, 2_000_500: 0.625})
    _queue(tmp_path)
    queue = yaml.safe_load((tmp_path / "campaign.yml").read_text())
    queue["entries"][0].update(name="neutral", method="huri-neutral", run="neutral/Zerith1-v0_1")
    (tmp_path / "campaign.yml").write_text(yaml.safe_dump(queue))
    lines = early_signal_lines(load_queue(tmp_path / "campaign.yml"), tmp_path / "results.md")

    assert lines[0].startswith("**neutral** (huri-neutral) against `huri/Zerith1-v0_1` (HuRi) and ")
    assert lines[0].endswith("(50 robots per case).")
    header = next(line for line in lines if line.startswith("| steps |"))
    columns = "| steps | return: huri-neutral / HuRi / PPO | length | fall rate | Table-1 mean (rows) |"
    assert header == columns
    rows = {line.split(" | ")[0]: line.rstrip(" |").split(" | ") for line in lines if line[2:3].isdigit()}
    assert set(rows) == {"| 1M", "| 2M"}
    # (1M, 2M] holds rollouts 10-19 of each run; each run's return rises by 1 per rollout from its start.
    expected = [np.mean([start + i for i in range(10, 20)]) for start in (50.0, 200.0, 300.0)]
    assert rows["| 2M"][1] == " / ".join(f"{value:.0f}" for value in expected)
    assert rows["| 1M"][4] == "0.375 / 0.250 (2.0M) / 0.125"  # HuRi's nearest row, with its own step
    assert rows["| 2M"][4] == "0.500 / 0.250 / 0.625"
    assert len(rows["| 2M"]) == 5  # no band shares
