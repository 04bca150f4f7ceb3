"""study.analyses.robustness_curves and robustness_plot (`study/scripts/robustness_curve.py`):
which checkpoints of a long run are evaluated, and what is written and drawn."""

from __future__ import annotations

import csv
import json

import numpy as np
import pytest

from sb3_huri.experiments.statistics import wilson_interval
from sb3_huri.runner.curve import append_row
from sb3_huri.runner.evaluation import TABLE1_SCENARIOS
from sb3_huri.runner.robustness import CASES, COLUMNS, read_rows, write_rows
from study.analyses import robustness_curves as curve
from study.analyses.robustness_plot import FORK_COLORS, fork_own_rows, plot_curve

CASE_VALUE = 0.5


def _fake_run(folder, checkpoint_steps, newest):
    """A run folder with checkpoint files (never loaded: the evaluation is replaced), a curve and a state."""
    (folder / "checkpoints").mkdir(parents=True)
    for steps in checkpoint_steps:
        (folder / "checkpoints" / f"rl_model_{steps}_steps.zip").write_bytes(b"")
        (folder / "checkpoints" / f"rl_model_vecnormalize_{steps}_steps.pkl").write_bytes(b"")
    (folder / "Zerith1-v0").mkdir()
    (folder / "Zerith1-v0.zip").write_bytes(b"")
    session = {"started": "then", "from_timesteps": 0, "to_timesteps": newest, "hardware": "x", "wall_s": 1}
    state = {"timesteps": newest, "curriculum_stage": 2, "wall_s": 10.0, "sessions": [session]}
    (folder / "Zerith1-v0" / "state.json").write_text(json.dumps(state))
    for steps in range(0, newest + 1, 100):
        append_row(folder, {"timesteps": steps, "wall_s": steps / 100, "scale": 0.5, "fall_rate": 0.25})


def test_rows_of_another_episode_count_are_evaluated_again_where_their_checkpoint_is_kept(
    tmp_path, monkeypatch
) -> None:
    run = tmp_path / "run"
    _fake_run(run, checkpoint_steps=[100, 200, 300, 400, 500, 700], newest=800)
    old = [  # written before the `episodes` column: 10 episodes per case
        {"timesteps": 100, "wall_s": 1, "hardware": "test", **dict.fromkeys(CASES, 0.1)},
        {"timesteps": 250, "wall_s": 2.5, "hardware": "test", **dict.fromkeys(CASES, 0.2)},
    ]
    with (run / "robustness.csv").open("w", newline="") as file:
        writer = csv.DictWriter(file, fieldnames=[c for c in COLUMNS if c != "episodes"])
        writer.writeheader()
        writer.writerows({**row, "table1_mean": 0.1, "vx_at_1.0": 0.9, "eval_s": 1} for row in old)
    evaluated = []

    def evaluate_checkpoint(model_file, normalizer_file, episodes, seed):
        evaluated.append((model_file.name, episodes))
        return {**dict.fromkeys(CASES, CASE_VALUE), "table1_mean": CASE_VALUE, "vx_at_1.0": 1.0}

    monkeypatch.setattr(curve, "evaluate_checkpoint", evaluate_checkpoint)
    assert curve.update_curve(run, every=300, episodes=50, seed=1000) == [100, 700, 800]

    # 100: redone (10 -> 50 episodes); 250: its checkpoint is gone, kept with 10, and still a point of the
    # curve: the next is at least 300 steps after it (700), then the newest model (800).
    assert evaluated == [
        ("rl_model_100_steps.zip", 50),
        ("rl_model_700_steps.zip", 50),
        ("Zerith1-v0.zip", 50),
    ]
    rows = read_rows(run)
    assert list(rows) == [100, 250, 700, 800]
    assert [rows[s]["episodes"] for s in rows] == ["50", "10", "50", "50"]
    assert float(rows[250]["sudden-feet"]) == 0.2 and float(rows[700]["sudden-feet"]) == CASE_VALUE
    assert rows[700]["wall_s"] == "7.0"  # the curve's wall time at that step

    summary = curve.write_summary(run)
    assert summary == run / "robustness.md"  # the run's own record: nothing outside the run is written
    text = summary.read_text()
    assert text.startswith("# run: status and robustness curve\n\n800 steps")
    assert "| 250 | 0.00 | 10 |" in text  # steps, wall hours, episodes
    low, high = wilson_interval(CASE_VALUE, 300)
    assert f"[{low:.2f}, {high:.2f}]" in text and "(300 episodes)" in text
    plot = tmp_path / "curve.png"
    plot_curve(run, plot)
    assert plot.stat().st_size > 10_000

    evaluated.clear()
    assert curve.update_curve(run, every=300, episodes=50, seed=1000) == []  # nothing new
    assert evaluated == []


def test_a_plot_of_a_run_without_evaluations_is_a_clear_error(tmp_path) -> None:
    run = tmp_path / "run"
    _fake_run(run, checkpoint_steps=[], newest=100)
    with pytest.raises(ValueError, match="no evaluated checkpoint"):
        plot_curve(run, tmp_path / "curve.png")


def test_a_fork_adds_its_own_rows_to_the_plot(tmp_path) -> None:
    run, fork = tmp_path / "run", tmp_path / "fork"
    _fake_run(run, checkpoint_steps=[], newest=300)
    _fake_run(fork, checkpoint_steps=[], newest=500)

    def row(steps: int, mean: float) -> dict:
        cases = dict.fromkeys(CASES, mean)
        return {
            "timesteps": steps,
            "wall_s": 1.0,
            "episodes": 50,
            **cases,
            "table1_mean": mean,
            "vx_at_1.0": 1.0,
        }

    write_rows(run, {s: row(s, 0.5) for s in (100, 300)})
    write_rows(fork, {s: row(s, 0.5) for s in (100, 300)})
    with pytest.raises(ValueError, match="no evaluated checkpoint beyond"):
        plot_curve(run, tmp_path / "curve.png", (fork,))
    write_rows(fork, {**read_rows(fork), 500: row(500, 0.7)})
    figure = plot_curve(run, tmp_path / "curve.png", (fork,) * 8)
    assert (tmp_path / "curve.png").stat().st_size > 10_000
    fork_lines = [line for line in figure.axes[0].get_lines() if line.get_label() == "fork: Table-1 mean"]
    assert len(fork_lines) == 8  # every fork is drawn, however many
    assert len({line.get_color() for line in fork_lines}) == len(FORK_COLORS)
    ppo = tmp_path / "huri-baseline" / "Zerith1-v0_1"
    _fake_run(ppo, checkpoint_steps=[], newest=400)
    with pytest.raises(ValueError, match="no evaluated checkpoint to plot"):
        plot_curve(run, tmp_path / "curve.png", versus=(ppo,))
    write_rows(ppo, {s: row(s, m) for s, m in ((200, 0.1), (400, 0.3))})
    figure = plot_curve(run, tmp_path / "curve.png", (fork,), versus=(ppo,))
    (versus_line,) = [
        line
        for line in figure.axes[0].get_lines()
        if line.get_label() == "huri-baseline/Zerith1-v0_1: Table-1 mean"
    ]
    assert list(versus_line.get_xdata()) == pytest.approx([2e-4, 4e-4])
    assert list(versus_line.get_ydata()) == [0.1, 0.3]
    assert versus_line.get_linestyle() == "--"
    # both trained on from step 300: the run's row at 500 is its own model, not the fork's
    write_rows(run, {**read_rows(run), 500: row(500, 0.6)})
    own = fork_own_rows(read_rows(run), read_rows(fork))
    assert [(step, float(r["table1_mean"])) for step, r in own] == [(300, 0.5), (500, 0.7)]


def test_the_trend_is_the_least_squares_slope_with_its_t_interval() -> None:
    rng = np.random.default_rng(0)
    steps = np.sort(rng.uniform(60e6, 120e6, size=12)).astype(int)
    values = 0.3 + 0.025 * steps / 1e7 + rng.normal(0, 0.04, size=12)
    slope, half = curve.trend(steps, values)
    # numpy's fit: its covariance is scaled by the residuals over n - 2 degrees of freedom
    (reference_slope, _), covariance = np.polyfit(steps / 1e7, values, 1, cov=True)
    t_975_10_dof = 2.2281388519649385  # the 97.5% quantile of Student's t with 10 degrees of freedom
    assert slope == pytest.approx(reference_slope)
    assert half == pytest.approx(np.sqrt(covariance[0, 0]) * t_975_10_dof)
    with pytest.raises(ValueError, match="at least 3 points"):
        curve.trend(steps[:2], values[:2])


def test_the_docs_state_the_trend_since_full_scale_only(tmp_path) -> None:
    run = tmp_path / "run"
    _fake_run(run, checkpoint_steps=[], newest=0)
    for steps, scale in ((100, 0.5), (200, 1.0), (300, 1.0)):
        append_row(run, {"timesteps": steps, "wall_s": 1, "scale": scale, "fall_rate": 0.0})
    rows = [  # a rise of 0.1 per 10M steps after full scale; a high row before it that must not count
        {"timesteps": str(s), **dict.fromkeys(curve.TREND_CASES, str(v))}
        for s, v in ((100, 0.9), (20_000_000, 0.2), (30_000_000, 0.3), (40_000_000, 0.4))
    ]
    sentence = curve.trend_markdown(run, rows)
    assert "(200 steps)" in sentence and "over 3 rows" in sentence
    assert "table1_mean +0.100 +- 0.000" in sentence and "sudden-feet +0.100" in sentence
    assert "vx_at_1.0 +0.100" in sentence
    assert "Over the last" not in sentence  # the window would hold every row since full scale
    assert curve.trend_markdown(run, rows[:3]) == ""  # two rows since full scale: no trend yet
    flat = [  # 0.1 per 10M steps up to 60M, then flat for the last 50M
        {"timesteps": str(s), **dict.fromkeys(curve.TREND_CASES, str(min(s, 60_000_000) / 1e8))}
        for s in range(20_000_000, 120_000_001, 10_000_000)
    ]
    sentence = curve.trend_markdown(run, flat)
    assert "over 11 rows" in sentence and "Over the last 50M steps (6 rows): table1_mean +0.000" in sentence


def test_the_shipping_check_names_every_criterion_a_row_misses() -> None:
    passing = {case: "0.9" for case in TABLE1_SCENARIOS}
    passing.update({"table1_mean": "0.9", "vx_at_1.0": "0.85", "nominal@1.0": "1.0", "nominal@0.5": "1.0"})
    passing["timesteps"] = "200000000"
    assert curve.unmet_ship_criteria(passing) == []
    assert "200,000,000" in curve.ship_markdown([passing])

    misses = {"sudden-feet": "0.4", "table1_mean": "0.75", "vx_at_1.0": "0.65", "nominal@0.5": "0.98"}
    failing = {**passing, **misses}
    unmet = curve.unmet_ship_criteria(failing)
    assert len(unmet) == 4
    assert any("sudden-feet 0.40" in u for u in unmet) and any("vx at 1 m/s 0.65" in u for u in unmet)
    assert any("nominal@0.5" in u for u in unmet) and any("Table-1 mean 0.750" in u for u in unmet)
    assert curve.ship_markdown([passing, failing]).startswith("Rows that meet")
    assert "sudden-feet 0.40" in curve.ship_markdown([failing])
