"""Survival over force magnitude: the env's reading options (one force per pair of bodies or one per body, a
push's hold time), the scaled cases, the curves and 50% scales, the resumable measurement, where a checkpoint
comes from, and the results page's section."""

from __future__ import annotations

import json
import math
import subprocess
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
import yaml
from scipy import stats

from sb3_huri.experiments.statistics import paired_difference_interval
from sb3_huri.runner.evaluation import TABLE1_SCENARIOS
from sb3_huri.runner.files import RunError
from study.analyses import force_magnitude as fm
from study.analyses.force_magnitude import (
    HEADLINE,
    Reading,
    half_survival_scale,
    paired_curve,
    stressed,
    survival_curve,
    survived,
    table1_difference,
)
from study.campaign.queue import load_queue
from study.results.evaluations import load_evaluations
from study.results.force_magnitude import _pair_lines, force_magnitude_section
from zerith_gym.core.disturbances import ForceSchedule
from zerith_gym.core.scenarios import SCENARIOS
from zerith_gym.core.task import scenario_arrays
from zerith_gym.zerith1 import constants as robot
from zerith_gym.zerith1.env import Zerith1Env
from zerith_gym.zerith1.task import HUMANOID_DRAWS, HUMANOID_TASK

ENV = "Zerith1-v0"


def _forces(scenario, steps: int, seed: int = 3, bodies=robot.FOOT_BODIES) -> tuple[np.ndarray, np.ndarray]:
    """The reported force and the force on each of `bodies` at each of `steps` control steps of a robot
    holding its stance: (steps, 3) and (steps, bodies, 3)."""
    env = Zerith1Env(scenario=scenario)
    env.reset(seed=seed)
    ids = [env.model.body(name).id for name in bodies]
    reported, applied = [], []
    for _ in range(steps):
        _, _, terminated, truncated, info = env.step(np.zeros(12))
        reported.append(info["external_force"].copy())
        applied.append(env.data.xfrc_applied[ids, :3].copy())
        assert not (terminated or truncated)
    return np.array(reported), np.array(applied)


def test_the_default_reading_applies_one_drawn_vector_to_both_bodies_as_before() -> None:
    """Today's forces, rebuilt from the robot's random stream: every step draws `STEP_DRAWS` uniforms after
    the reset's; a continuous force is drawn from the step's two force uniforms every 5 steps."""
    assert ForceSchedule().per_body is False
    assert not any(s.force.per_body for s in SCENARIOS.values() if isinstance(s.force, ForceSchedule))
    reported, applied = _forces("continuous-feet", 12)
    rng = np.random.Generator(np.random.PCG64(3))
    rng.random(HUMANOID_DRAWS.reset)
    for step in range(12):
        uniforms = rng.random(HUMANOID_DRAWS.step)
        if step % 5 == 0:
            norm, turn = (
                100.0 * uniforms[HUMANOID_DRAWS.force][0],
                2 * np.pi * uniforms[HUMANOID_DRAWS.force][1],
            )
            expected = np.array([norm * np.cos(turn), norm * np.sin(turn), 0.0])
        np.testing.assert_allclose(reported[step], expected, rtol=1e-12)
        np.testing.assert_array_equal(applied[step], [reported[step], reported[step]])
    explicit = replace(
        SCENARIOS["continuous-feet"], force=replace(SCENARIOS["continuous-feet"].force, per_body=False)
    )
    assert np.array_equal(_forces(explicit, 12)[1], applied)


@pytest.mark.parametrize(
    "case,bodies", [("continuous-feet", robot.FOOT_BODIES), ("continuous-hands", robot.HAND_BODIES)]
)
def test_a_per_body_reading_draws_each_body_its_own_force(case: str, bodies: tuple[str, ...]) -> None:
    _, shared = _forces(case, 15, bodies=bodies)
    reported, own = _forces(stressed(case, 1.0, Reading(per_body=True)), 15, bodies=bodies)
    np.testing.assert_array_equal(own[:, 0], shared[:, 0])  # the first body's: the robot's stream, untouched
    np.testing.assert_array_equal(reported, own[:, 0])
    second = own[:, 1]
    assert not np.allclose(second, own[:, 0])
    for start in (0, 5, 10):  # drawn every 5 steps, held in between, within the case's range
        assert not np.allclose(second[start], own[start, 0])
        assert np.all(second[start : start + 5] == second[start])
        assert 0.0 < np.linalg.norm(second[start]) <= 100.0 and second[start, 2] == 0.0
    assert not np.allclose(second[0], second[5])
    assert np.array_equal(_forces(stressed(case, 1.0, Reading(per_body=True)), 15, bodies=bodies)[1], own)


def test_the_mjx_backend_refuses_a_per_body_schedule() -> None:
    pytest.importorskip("jax")
    import zerith_gym

    with pytest.raises(ValueError, match="per body"):
        zerith_gym.make_vec_env(
            2, seed=0, scenario=stressed("sudden-feet", 1.0, Reading(per_body=True)), backend="mjx"
        )


@pytest.mark.parametrize("hold", [1, 5])
def test_a_push_lasts_the_hold_time_asked_for(hold: int) -> None:
    scenario = stressed("sudden-feet", 1.0, Reading(hold_steps=hold))
    acting = np.flatnonzero(scenario_arrays(scenario, None, 1000, HUMANOID_TASK).force_due[:1000, 1])
    assert acting.tolist() == [t for start in range(100, 1000, 100) for t in range(start, start + hold)]
    reported, applied = _forces(scenario, 100 + hold + 2)
    magnitude = np.linalg.norm(reported, axis=1)
    assert np.flatnonzero(magnitude).tolist() == list(range(100, 100 + hold))
    assert np.all((magnitude[100 : 100 + hold] >= 150.0) & (magnitude[100 : 100 + hold] <= 200.0))
    assert np.all(np.linalg.norm(applied[100 + hold :], axis=2) == 0.0)


def test_cases_scale_their_force_and_fig4_cases_their_robot_too() -> None:
    assert stressed("sudden-hands", 1.0).force == SCENARIOS["sudden-hands"].force
    assert stressed("load-friction", 1.0).randomization == SCENARIOS["load-friction"].randomization
    half = stressed("sudden-hands", 0.5)
    assert (
        half.force.magnitude == (75.0, 100.0)
        and half.randomization == SCENARIOS["sudden-hands"].randomization
    )
    fig4 = stressed("load-friction", 0.5).randomization
    assert fig4.added_mass == (-1.5, 4.0)
    np.testing.assert_allclose(fig4.friction, (0.1**0.5, 2**0.5))
    assert stressed("load-friction", 1.5).randomization.friction[0] > 0.0
    nominal = stressed("sudden-feet", 1.0, Reading("nominal"))
    assert nominal.randomization == SCENARIOS["nominal"].randomization
    assert Reading("nominal", per_body=True, hold_steps=1).canonical("load") == HEADLINE
    assert Reading(per_body=True, hold_steps=1).canonical("continuous-hands") == Reading(per_body=True)
    assert Reading(per_body=True, hold_steps=1).canonical("sudden-centroid") == Reading(hold_steps=1)
    assert Reading.parse("nominal:per-body:hold1") == Reading("nominal", True, 1)
    with pytest.raises(ValueError):
        Reading.parse("test:each:hold5")


def test_half_survival_scale_interpolates_the_first_fall_below_half() -> None:
    assert half_survival_scale([0.5, 1.0, 1.5], [0.9, 0.7, 0.3]) == pytest.approx(1.25)
    assert half_survival_scale([0.5, 1.0, 1.5], [0.9, 0.5, 0.1]) == pytest.approx(1.0)
    assert half_survival_scale([0.1, 0.4, 0.7, 1.0], [1.0, 0.4, 0.6, 0.2]) == pytest.approx(
        0.1 + 0.5 / 0.6 * 0.3
    )
    assert half_survival_scale([0.5, 1.0], [0.8, 0.6]) == math.inf
    assert half_survival_scale([0.5, 1.0], [0.3, 0.1]) == -math.inf
    assert math.isnan(half_survival_scale([], []))
    assert (
        fm.scale_cell(math.inf, [0.1, 1.5]) == "> 1.5x" and fm.scale_cell(-math.inf, [0.1, 1.5]) == "< 0.1x"
    )


def _cell(alive: list[int]) -> dict:
    return {"survive": float(np.mean(alive)), "fall_step": [None if a else 7 for a in alive]}


def _record(steps: int, cells: dict[str, dict[str, dict[str, list[int]]]]) -> dict:
    """A measurements file's contents from 1/0 outcomes by reading key, case and scale key."""
    measurements = {
        key: {
            case: {scale: _cell(alive) for scale, alive in scales.items()} for case, scales in cases.items()
        }
        for key, cases in cells.items()
    }
    return {
        "env_id": ENV, "steps": steps, "evaluated_steps": steps, "model": f"{ENV}.zip", "eval_s": 1.0,
        "settings": {"robots": 4, "seed": 2000, "episode_steps": 1000}, "measurements": measurements,
    }  # fmt: skip


def test_curves_pairs_and_table1_differences_from_the_robots_outcomes() -> None:
    a = _record(
        10,
        {"test:pair:hold5": {"sudden-feet": {"1.25": [0, 0, 1, 0], "0.5": [1, 1, 1, 1], "1": [1, 0, 1, 1]}}},
    )
    b = _record(10, {"test:pair:hold5": {"sudden-feet": {"1": [1, 1, 1, 1], "0.5": [1, 1, 1, 1]}}})
    outcomes = survived(a, HEADLINE, "sudden-feet")
    assert list(outcomes) == [0.5, 1.0, 1.25]  # in numeric order, whatever the file's key order
    scales, shares, robots = survival_curve(outcomes)
    assert shares.tolist() == [1.0, 0.75, 0.25] and robots.tolist() == [4, 4, 4]
    assert half_survival_scale(scales, shares) == pytest.approx(1.0 + 0.25 / 0.5 * 0.25)
    assert survived(a, Reading(per_body=True), "sudden-centroid") == {}
    rows = paired_curve(outcomes, survived(b, HEADLINE, "sudden-feet"))
    assert [row[0] for row in rows] == [0.5, 1.0]
    assert rows[1][1:] == paired_difference_interval(np.array([1, 0, 1, 1], bool), np.ones(4, bool))
    # The Table-1 mean: each robot's survival averaged over the six cases, a t interval over the robots.
    first = {case: [1, 0, 1, 1] for case in TABLE1_SCENARIOS} | {"sudden-feet": [0, 0, 1, 1]}
    second = {case: [1, 1, 1, 0] for case in TABLE1_SCENARIOS}
    a = _record(10, {"test:pair:hold5": {case: {"1": alive} for case, alive in first.items()}})
    b = _record(10, {"test:pair:hold5": {case: {"1": alive} for case, alive in second.items()}})
    per_robot = np.mean([np.subtract(first[c], second[c]) for c in TABLE1_SCENARIOS], axis=0)
    half = stats.t.ppf(0.975, 3) * per_robot.std(ddof=1) / 2
    mean, low, high = table1_difference(a, b, HEADLINE)
    assert (mean, low, high) == pytest.approx(
        (per_robot.mean(), per_robot.mean() - half, per_robot.mean() + half)
    )
    assert all(math.isnan(v) for v in table1_difference(a, b, Reading(per_body=True)))


class _Model:
    num_timesteps = 500


@pytest.fixture
def fake_agent(tmp_path: Path, monkeypatch):
    """A run folder whose checkpoint at 500 steps is a stand-in model, and an `evaluate` that counts its
    calls and fails on demand (robot i falls at step i in every case)."""
    import contextlib

    run = tmp_path / "run"
    run.mkdir()
    calls: list[str] = []
    fail_at: list[int] = []

    @contextlib.contextmanager
    def files(run_: Path, steps: int, env_id: str = ENV):
        yield steps, run_ / "model.zip", None, "model.zip"

    def evaluate(model, normalizer, scenario, command, robots, seed, **kwargs):
        assert kwargs["per_robot"] and seed == 2000 and command is None
        calls.append(scenario.name)
        if len(calls) in fail_at:
            raise KeyboardInterrupt
        fall = np.where(np.arange(robots) % 2 == 0, np.arange(robots), np.nan)
        return {"survive": float(np.isnan(fall).mean()), "fall_step": fall}

    monkeypatch.setattr(fm, "checkpoint_files", files)
    monkeypatch.setattr(fm, "evaluate", evaluate)
    monkeypatch.setattr("sb3_huri.runner.folder.load_checkpoint", lambda model, normalizer: (_Model(), None))
    return run, calls, fail_at


def test_a_measurement_skips_what_is_done_and_continues_after_an_interruption(fake_agent) -> None:
    run, calls, fail_at = fake_agent
    cases = ("continuous-centroid", "sudden-feet")
    fail_at.append(3)
    with pytest.raises(KeyboardInterrupt):
        fm.measure_agent(run, 500, cases=cases, scales=(0.5, 1.0), robots=4)
    fail_at.clear()
    path = fm.result_path(run, 500)
    assert sum(len(s) for c in json.loads(path.read_text())["measurements"].values() for s in c.values()) == 2
    calls.clear()
    fm.measure_agent(run, 500, cases=cases, scales=(0.5, 1.0), robots=4)
    assert calls == ["sudden-feetx0.5[test:pair:hold5]", "sudden-feetx1[test:pair:hold5]"]
    calls.clear()
    fm.measure_agent(run, 500, cases=cases, scales=(0.5, 1.0), robots=4)
    assert calls == []
    # Per body: only the feet case changes; a short push: only the sudden case; both: nothing new.
    fm.measure_agent(run, 500, fm.READINGS, cases=cases, scales=(1.0,), robots=4)
    assert calls == [
        f"sudden-feetx1[test:{key}]" for key in ("pair:hold1", "per-body:hold5", "per-body:hold1")
    ]
    record = fm.read_record(path)
    assert record["measurements"]["test:pair:hold5"]["sudden-feet"]["1"]["fall_step"] == [0, None, 2, None]
    assert survived(record, Reading(per_body=True, hold_steps=1), "continuous-centroid")[1.0].tolist() == [
        False, True, False, True
    ]  # fmt: skip
    with pytest.raises(RunError, match="settings"):
        fm.measure_agent(run, 500, cases=cases, scales=(1.0,), robots=6)


def _git(folder: Path, *args: str) -> None:
    subprocess.run(["git", "-C", str(folder), *args], check=True, capture_output=True)


def test_a_checkpoint_not_held_comes_from_the_commit_of_its_state_else_the_nearest_model(
    tmp_path: Path,
) -> None:
    run = tmp_path / "run"
    (run / ENV).mkdir(parents=True)
    _git(tmp_path, "init", "-q")
    for steps, content in ((100, b"model at 100"), (200, b"model at 200")):
        (run / f"{ENV}.zip").write_bytes(content)
        (run / ENV / "vecnormalize.pkl").write_bytes(b"statistics at %d" % steps)
        (run / ENV / "state.json").write_text(json.dumps({"timesteps": steps}))
        _git(tmp_path, "add", "-A")
        _git(tmp_path, "-c", "user.name=t", "-c", "user.email=t@t", "commit", "-q", "-m", f"{steps}")
    with fm.checkpoint_files(run, 100) as (steps, model, normalizer, source):
        assert steps == 100 and model.read_bytes() == b"model at 100" and source.startswith("git ")
        assert normalizer is not None and normalizer.read_bytes() == b"statistics at 100"
    with fm.checkpoint_files(run, 200) as (steps, model, _, source):
        assert steps == 200 and model.read_bytes() == b"model at 200" and source == f"{ENV}.zip"
    with fm.checkpoint_files(run, 300) as (steps, model, _, source):
        assert steps == 200 and model.read_bytes() == b"model at 200" and "nearest" in source


def _campaign(root: Path, per_body_second: list[int]) -> list:
    """Two evaluated runs (HuRi and PPO, seed 0) with measurements under the headline and per body: under
    the headline PPO survives more, per body HuRi does (the second's feet outcomes: `per_body_second`)."""
    root.mkdir(parents=True, exist_ok=True)
    (root / "preset.yml").write_text(f"{ENV}: {{}}\n")
    entries = []
    for name, method, first in (("huri-s0", "huri", [1, 1, 0, 1]), ("ppo-s0", "huri-baseline", [1, 1, 1, 1])):
        run = root / method / f"{ENV}_1"
        (run / ENV).mkdir(parents=True)
        (run / ENV / "state.json").write_text(json.dumps({"timesteps": 1000}))
        evaluation = {"entry": name, "steps": 1000, "settings": {"episodes": 4, "seed": 2000}, "cases": {}}
        (run / "evaluations").mkdir()
        (run / "evaluations" / "1000.json").write_text(json.dumps(evaluation))
        feet = [1, 1, 1, 0] if method == "huri" else per_body_second
        cells = {
            "test:pair:hold5": {
                case: {s: first if s != "1.5" else [0, 0, 0, 0] for s in ("0.5", "1", "1.5")}
                for case in fm.CASES
            },
            "test:per-body:hold5": {
                case: {"1": feet} for case in fm.CASES if case.endswith(("hands", "feet"))
            },
        }
        (run / "evaluations" / f"1000{fm.SUFFIX}").write_text(json.dumps(_record(1000, cells)))
        entries.append({"name": name, "protocol": "robust", "method": method, "seed": 0,
                        "run": f"{method}/{ENV}_1", "conf": "preset.yml", "steps": 1000})  # fmt: skip
    (root / "campaign.yml").write_text(yaml.safe_dump({"entries": entries}))
    return load_evaluations(load_queue(root / "campaign.yml"))


def test_the_page_section_says_its_reading_and_renders_the_same_figure_twice(tmp_path: Path) -> None:
    evaluations = _campaign(tmp_path, per_body_second=[0, 1, 0, 1])
    out = tmp_path / "docs" / "results.md"
    figures = out.with_suffix("")
    figures.mkdir(parents=True)
    lines = force_magnitude_section(evaluations, figures, out)
    page = "\n".join(lines)
    assert "**Headline reading: one force per pair of hands / feet, 0.1-s pushes**" in page
    assert "can depend on the reading" in page
    huri_row = next(line for line in lines if line.startswith("| huri-s0 @ 0.0M |"))
    assert huri_row.split(" | ")[2] == "1.17x (0.75)"  # 0.75 at 1x, 0 at 1.5x: 1 + 0.25 / 0.75 * 0.5
    assert (
        next(line for line in lines if line.startswith("| ppo-s0 @ 0.0M |")).split(" | ")[2] == "1.25x (1.00)"
    )
    assert (
        "**The order depends on the reading** (Table-1 mean at 1x, point estimates): Baseline (PPO) ahead "
        "under test:pair:hold5; HuRi ahead under test:per-body:hold5."
    ) in page
    # Every reading of each agent: PPO's per-body Table-1 mean at 1x averages, per robot, the centroid cases
    # (the headline's outcomes, all alive) with the hands' and feet's per-body outcomes [0, 1, 0, 1].
    per_body = np.mean([np.mean([1, 1, *[alive] * 4]) for alive in (0, 1, 0, 1)])
    ppo_readings = next(line for line in lines if line.startswith("| ppo-s0 @ 0.0M | 1.000 |"))
    assert ppo_readings == f"| ppo-s0 @ 0.0M | 1.000 | - | {per_body:.3f} | - | - | - |"
    assert "`test:per-body:hold5`: a force per hand / foot, 0.1-s pushes" in page
    assert "![force_magnitude](results/force_magnitude.png)" in page
    figure = figures / "force_magnitude.png"
    content, written = figure.read_bytes(), figure.stat().st_mtime_ns
    assert content[:8] == b"\x89PNG\r\n\x1a\n" and b"matplotlib" not in content
    assert force_magnitude_section(evaluations, figures, out) == lines
    assert figure.read_bytes() == content and figure.stat().st_mtime_ns == written
    same = _campaign(tmp_path / "same", per_body_second=[1, 1, 1, 1])
    records = [fm.agent_record(e.entry.run, e.steps) for e in same]
    assert "The same order under every reading of the test robot measured (point estimates)." in _pair_lines(
        *same, *records
    )


def test_a_section_without_measurements_says_so_and_draws_nothing(tmp_path: Path) -> None:
    evaluations = _campaign(tmp_path, per_body_second=[1, 1, 1, 1])
    for e in evaluations:
        fm.result_path(e.entry.run, 1000).unlink()
    stale = tmp_path / "results" / "force_magnitude.png"
    stale.parent.mkdir()
    stale.write_bytes(b"old")
    lines = force_magnitude_section(evaluations, stale.parent, tmp_path / "results.md")
    assert "No agent is measured yet (`study/scripts/force_magnitude.py`)." in lines and not stale.exists()
