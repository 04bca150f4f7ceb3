"""The risk levels an agent sets on the states it visits (``study.analyses.risk_levels``,
``study/scripts/risk_levels.py``) and their section of the results page
(``study.results.risk_levels``).

The measurement runs on a real HuRi model with the percentile band, trained a few rollouts on Zerith1-v0, its
band then loaded at the 30th and 70th percentiles of the IQRs of the states measured (so that states fall on
every side of it); the page is built from hand-made files.
"""

from __future__ import annotations

import json
import runpy
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest
import yaml

from sb3_huri.experiments.errors import ExperimentError
from sb3_huri.runner.evaluation import RiskStates, evaluate
from sb3_huri.runner.files import RunError
from study.analyses import risk_levels as analysis
from study.analyses.risk_levels import (
    case_statistics,
    choose_checkpoint,
    default_cases,
    measure_risk_levels,
    risk_levels_files,
    risk_levels_path,
)
from study.campaign.queue import load_queue
from study.results.risk_levels import (
    order_sentence,
    risk_family,
    risk_levels_section,
    rnd_sentence,
)

ENV = "Zerith1-v0"
STEPS = 64
EPISODE_STEPS = 25


@pytest.fixture(scope="module")
def run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A run folder of a HuRi model with the percentile band, trained 64 steps (no normalizer), that trained
    in the `robust` scenario; its band loaded inside the IQRs of the measured states."""
    import zerith_gym
    from sb3_huri import HuRiPPO

    folder = tmp_path_factory.mktemp("risk") / "run"
    (folder / ENV).mkdir(parents=True)
    env = zerith_gym.make_vec_env(4, seed=1, workers=0)
    model = HuRiPPO(
        "MultiInputPolicy", env, method="huri-percentile", n_steps=16, n_epochs=1, n_quantiles=8,
        policy_kwargs={"net_arch": [8]}, seed=3,
    )  # fmt: skip
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # rewards are not normalized here
        model.learn(STEPS)
    model.save(folder / f"{ENV}.zip")
    env.close()
    # The band its training left lies where the untrained critic's IQRs were: put it inside the measured ones.
    probes = [
        evaluate(model, None, case, (1.0, 0.0, 0.0), 2, 11, episode_steps=EPISODE_STEPS, risk_states=True)
        for case in ("nominal", "sudden-centroid")
    ]
    iqr = np.concatenate([probe["states"].iqr for probe in probes])
    band = tuple(float(value) for value in np.percentile(iqr, (30, 70)))
    HuRiPPO.load(folder / f"{ENV}.zip", device="cpu", iqr_thresholds=band).save(folder / f"{ENV}.zip")
    (folder / ENV / "state.json").write_text(json.dumps({"timesteps": STEPS}))
    (folder / ENV / "config.yml").write_text(yaml.safe_dump({"env_kwargs": {"scenario": "robust"}}))
    (folder / ENV / "args.yml").write_text(yaml.safe_dump({"env": ENV, "algo": "huri-percentile"}))
    return folder


def _measure(run: Path, cases: list[str], robots: int = 2) -> dict:
    path = measure_risk_levels(run, cases=cases, robots=robots, seed=11, episode_steps=EPISODE_STEPS)
    assert path == risk_levels_path(run, STEPS) == run / "evaluations" / f"{STEPS}-risk_levels.json"
    return json.loads(path.read_text())


def test_the_shares_are_the_bands_definition_on_the_states_visited(run: Path) -> None:
    from sb3_huri.runner.folder import load_checkpoint

    data = _measure(run, ["nominal@1", "sudden-centroid"])
    model, _ = load_checkpoint(run / f"{ENV}.zip", None)
    t_min, t_max = model.risk_model.iqr_thresholds
    assert data["band"] == {
        "reading": "percentile", "thresholds": [t_min, t_max], "levels": [-1.0, 0.0, 1.0],
        "distortion": "wang", "use_iqr": True, "use_rnd": True,
    }  # fmt: skip
    assert 0 < t_min < t_max and (t_min, t_max) != (0.3, 0.7)
    assert (data["steps"], data["method"], data["training_scenario"]) == (STEPS, "huri-percentile", "robust")
    assert data["settings"] == {"robots": 2, "seed": 11, "episode_steps": EPISODE_STEPS}
    for case in ("nominal@1", "sudden-centroid"):
        # The same robots again, read state by state: the band's definition applied here to the IQRs.
        name, command = analysis.parse_case(case)
        result = evaluate(
            model, None, name, command, 2, 11, episode_steps=EPISODE_STEPS, risk_states=True, per_robot=True
        )
        states: RiskStates = result["states"]
        iqr = states.iqr.astype(np.float64)
        below = (states.risk_iqr == -1).mean()
        within = (states.risk_iqr == 0).mean()
        above = (states.risk_iqr == 1).mean()
        measured = data["cases"][case]
        assert measured["robot_steps"] == len(iqr) <= 2 * EPISODE_STEPS
        assert (measured["below"], measured["within"], measured["above"]) == (below, within, above)
        assert below == pytest.approx(np.mean(iqr < t_min), abs=1e-12)
        assert above == pytest.approx(np.mean(iqr > t_max), abs=1e-12)
        assert measured["beta"] == pytest.approx(measured["beta_iqr"] + measured["beta_rnd"], abs=1e-6)
        assert measured["beta_iqr"] == pytest.approx(above - below, abs=1e-9)
        assert measured["beta_rnd"] == pytest.approx(np.tanh(states.rnd_error).mean(), abs=1e-6)
        assert measured["beta_rnd_above_half"] == np.mean(states.risk_rnd > 0.5)
        assert measured["iqr_median"] == pytest.approx(np.median(iqr), abs=1e-6)
        assert measured["survive"] == result["survive"]
        # Each state's robot and step: a robot's steps run from 0 to its fall, or to the time limit.
        fall = result["fall_step"]
        for robot in range(2):
            length = EPISODE_STEPS if np.isnan(fall[robot]) else int(fall[robot]) + 1
            assert states.step[states.robot == robot].tolist() == list(range(length))
        before = np.array(
            [not np.isnan(fall[r]) and fall[r] - s < analysis.FALL_WINDOW_STEPS
             for r, s in zip(states.robot, states.step, strict=True)]
        )  # fmt: skip
        assert measured["falls"] == np.count_nonzero(~np.isnan(fall))
        assert measured["before_fall_states"] == before.sum()
        assert measured["beta_elsewhere"] == pytest.approx(states.risk[~before].astype(float).mean())
    shares = [data["cases"][case][side] for case in data["cases"] for side in ("below", "within", "above")]
    assert sum(share > 0 for share in shares) >= 3  # states on several sides of the band: a real check


def test_a_second_call_measures_only_the_new_cases_and_refuses_other_settings(run: Path, monkeypatch) -> None:
    first = _measure(run, ["nominal@1"])
    calls = []
    real = analysis.evaluate

    def counted(*args, **kwargs):
        calls.append(args[2])
        return real(*args, **kwargs)

    monkeypatch.setattr(analysis, "evaluate", counted)
    # The same checkpoint read from another file (kept in checkpoints/ once the run trained on) adds to it.
    path = risk_levels_path(run, STEPS)
    path.write_text(json.dumps({**first, "model": f"checkpoints/rl_model_{STEPS}_steps.zip"}))
    again = _measure(run, ["nominal@1", "uneven"])
    assert calls == ["uneven"]
    assert again["cases"]["nominal@1"] == first["cases"]["nominal@1"]  # read back as it was written
    assert set(again["cases"]) >= {"nominal@1", "uneven"} and again["eval_s"] >= first["eval_s"]
    assert "entry" not in again  # the campaign takes a file with an `entry` for a final evaluation
    with pytest.raises(RunError, match="other settings"):
        _measure(run, ["nominal@1"], robots=3)
    assert risk_levels_files(run) == {STEPS: risk_levels_path(run, STEPS)}


def test_the_default_cases_follow_the_robot_and_its_training_scenario() -> None:
    assert default_cases("zerith1", "robust") == [
        "nominal@1", "sudden-centroid", "uneven", "robust@1", "robust", "nominal@0.5",
    ]  # fmt: skip
    assert default_cases("go2like", "quadruped-rough") == [
        "nominal@1", "platform-0.40", "quadruped-rough@1", "quadruped-rough", "nominal@0.5",
    ]  # fmt: skip


def test_the_checkpoint_is_the_final_evaluations_if_kept_else_the_newest(tmp_path: Path) -> None:
    run = tmp_path / "run"
    (run / ENV).mkdir(parents=True)
    (run / f"{ENV}.zip").write_bytes(b"model")
    (run / ENV / "state.json").write_text(json.dumps({"timesteps": 3000}))
    (run / "checkpoints").mkdir()
    (run / "checkpoints" / "rl_model_1000_steps.zip").write_bytes(b"model")
    (run / "evaluations").mkdir()
    (run / "evaluations" / "2000.json").write_text("{}")
    steps, model, _, why = choose_checkpoint(run, ENV)
    assert (steps, model.name) == (3000, f"{ENV}.zip") and "2,000 steps, is not kept" in why
    (run / "evaluations" / "1000.json").write_text("{}")
    (run / "evaluations" / "2000.json").unlink()
    assert choose_checkpoint(run, ENV)[:2] == (1000, run / "checkpoints" / "rl_model_1000_steps.zip")
    assert choose_checkpoint(run, ENV, 1500)[0] == 3000
    with pytest.raises(ExperimentError, match="no model at or after 4,000 steps"):
        choose_checkpoint(run, ENV, 4000)


def test_a_model_replaced_while_it_is_read_is_refused(run: Path, tmp_path: Path) -> None:
    import os
    import shutil

    copy = tmp_path / "run"
    shutil.copytree(run, copy, ignore=shutil.ignore_patterns("evaluations"))
    (copy / ENV / "state.json").write_text(json.dumps({"timesteps": STEPS + 64}))  # saved after the zip
    with pytest.raises(ExperimentError, match="saved a new checkpoint while it was read"):
        measure_risk_levels(copy, cases=["nominal@1"], robots=1, episode_steps=2)
    assert not (copy / "evaluations").exists()

    # A normalizer written milliseconds after the state (a git checkout) is the same checkpoint's; one
    # written seconds after it is a later save's.
    import gymnasium as gym
    from stable_baselines3.common.vec_env import DummyVecEnv, VecNormalize

    state, normalizer = copy / ENV / "state.json", copy / ENV / "vecnormalize.pkl"
    state.write_text(json.dumps({"timesteps": STEPS}))
    VecNormalize(DummyVecEnv([lambda: gym.make("Pendulum-v1")])).save(str(normalizer))
    model_file = copy / f"{ENV}.zip"
    written = state.stat().st_mtime
    os.utime(normalizer, (written + 0.005, written + 0.005))
    model, _ = analysis.load_measured(copy, ENV, STEPS, model_file, normalizer)
    assert model.num_timesteps == STEPS
    with pytest.raises(ExperimentError, match="saved a new checkpoint"):
        os.utime(normalizer, (written + 5, written + 5))
        analysis.load_measured(copy, ENV, STEPS, model_file, normalizer)


def test_case_statistics_counts_the_band_edges_as_within() -> None:
    iqr = np.array([0.1, 0.3, 0.5, 0.7, 0.9], dtype=np.float32)
    risk_iqr = np.array([-1, 0, 0, 0, 1], dtype=np.float32)
    rnd = np.array([0.0, 0.2, 0.4, 0.6, 0.8], dtype=np.float32)
    states = RiskStates(risk_iqr + rnd, risk_iqr, rnd, iqr, np.arctanh(rnd))
    statistics = case_statistics(states, (0.3, 0.7))
    assert (statistics["below"], statistics["within"], statistics["above"]) == (0.2, 0.6, 0.2)
    assert statistics["beta_rnd_above_half"] == pytest.approx(0.4)
    assert statistics["beta_rnd_p90"] == pytest.approx(np.quantile(rnd.astype(float), 0.9))
    assert statistics["iqr_median"] == pytest.approx(0.5)


def test_fall_statistics_hold_the_last_second_before_each_fall_against_the_rest() -> None:
    """Robot 0 falls at step 60 (61 states: the last 50 are before its fall), robot 1 never (70 states)."""
    robot = np.concatenate([np.zeros(61, dtype=int), np.ones(70, dtype=int)])
    step = np.concatenate([np.arange(61), np.arange(70)])
    iqr = np.where(robot == 0, step / 60.0, 0.2).astype(np.float32)  # rises towards robot 0's fall
    risk = np.where(iqr > 0.7, 1.0, 0.0).astype(np.float32)
    zeros = np.zeros_like(iqr)
    states = RiskStates(risk, risk, zeros, iqr, zeros, robot, step)
    statistics = analysis.fall_statistics(states, np.array([60.0, np.nan]), (0.3, 0.7))
    before = (robot == 0) & (step > 60 - analysis.FALL_WINDOW_STEPS)
    assert statistics["falls"] == 1 and statistics["before_fall_states"] == before.sum() == 50
    assert statistics["above_before_fall"] == pytest.approx(np.mean(iqr[before] > 0.7))
    assert statistics["above_elsewhere"] == pytest.approx(np.mean(iqr[~before] > 0.7)) == 0.0
    assert statistics["beta_before_fall"] == pytest.approx(risk[before].mean())
    survivors = analysis.fall_statistics(states, np.array([np.nan, np.nan]), (0.3, 0.7))
    assert survivors["falls"] == 0 and survivors["beta_before_fall"] is None
    record = {"cases": {"a": statistics, "b": {key: 0 for key in statistics if key != "falls"}}}
    assert analysis.measured_cases(record) == {"a"}  # a file measured before the falls' keys: measured again


def _case(beta: float, rnd: float = 0.05, p90: float = 0.08, high: float = 0.0) -> dict:
    return {
        "below": 0.5, "within": 0.3, "above": 0.2, "beta": beta, "beta_iqr": beta - rnd, "beta_rnd": rnd,
        "beta_rnd_p90": p90, "beta_rnd_above_half": high, "iqr_median": 0.25, "survive": 1.0,
        "robot_steps": 5000,
    }  # fmt: skip


def _data(plane: float, push: float, uneven: float, distortion: str = "wang", **extra: dict) -> dict:
    return {
        "steps": 1000, "method": "huri", "robot": "zerith1",
        "band": {"reading": "absolute", "thresholds": [0.3, 0.7], "levels": [-1.0, 0.0, 1.0],
                 "distortion": distortion, "use_iqr": True, "use_rnd": True},
        "roles": {"plane": "nominal@1", "push": "sudden-centroid", "uneven": "uneven"},
        "settings": {"robots": 5, "seed": 2000, "episode_steps": 1000}, "eval_s": 1.0,
        "cases": {
            "nominal@1": _case(plane), "sudden-centroid": _case(push), "uneven": _case(uneven), **extra
        },
    }  # fmt: skip


def test_the_order_sentence_says_whether_uneven_beats_push_beats_plane() -> None:
    holds = order_sentence(_data(-0.9, -0.2, 0.4))
    assert holds.startswith("mean beta +0.400 on uneven ground (`uneven`), -0.200 under pushes")
    assert "-0.900 on the plane (`nominal@1`): the paper's order holds" in holds
    broken = order_sentence(_data(-0.9, 0.5, 0.4))
    assert broken.endswith("does not hold (not more risk-averse on uneven ground than under pushes)")
    both = order_sentence(_data(0.6, 0.5, 0.4))
    assert "than under pushes; not more risk-averse under pushes than on the plane)" in both
    assert "holds" in order_sentence(_data(1.0, 0.8, 0.6, "cvar"))  # CVaR: a lower alpha is more averse
    assert order_sentence(_data(1.0, 0.8, 0.6, "cvar")).startswith("mean alpha")
    missing = _data(-0.9, -0.2, 0.4)
    del missing["cases"]["uneven"]
    assert order_sentence(missing) == "the paper's order cannot be read: `uneven` not measured"


def test_the_fall_sentence_pools_the_cases_where_robots_fell() -> None:
    from study.results.risk_levels import fall_sentence

    data = _data(-0.5, 0.5, 0.0)
    assert fall_sentence(data) == "before a fall: not measured in this file"
    falls = dict(falls=0, before_fall_states=0, beta_before_fall=None, above_before_fall=None)
    for case in data["cases"].values():
        case.update(falls, beta_elsewhere=0.0, above_elsewhere=0.0)
    assert fall_sentence(data) == "no robot fell in the 3 cases measured"
    data["cases"]["sudden-centroid"].update(
        falls=2, before_fall_states=100, beta_before_fall=0.9, above_before_fall=0.8, beta_elsewhere=0.1,
        above_elsewhere=0.2,
    )  # fmt: skip
    data["cases"]["uneven"].update(
        falls=1, before_fall_states=50, beta_before_fall=0.3, above_before_fall=0.2, beta_elsewhere=-0.5,
        above_elsewhere=0.0,
    )  # fmt: skip
    # Pooled by states: 100 and 50 before the falls; 4,900 and 4,950 other states (5,000 read per case).
    before = (100 * 0.9 + 50 * 0.3) / 150, (100 * 0.8 + 50 * 0.2) / 150
    other = (4900 * 0.1 + 4950 * -0.5) / 9850, (4900 * 0.2) / 9850
    assert fall_sentence(data) == (
        f"in the last 1 s before its robots' 3 falls (2 cases), mean beta {before[0]:+.2f} and "
        f"{before[1]:.0%} of the states above the band, against {other[0]:+.2f} and {other[1]:.0%} over "
        "the other states of those cases"
    )
    # Every state of those cases within a second of a fall: nothing to hold them against.
    for case in ("sudden-centroid", "uneven"):
        values = data["cases"][case]
        values.update(robot_steps=values["before_fall_states"], beta_elsewhere=None, above_elsewhere=None)
    assert fall_sentence(data).endswith("of the states above the band; those cases hold no other states")


def test_the_rnd_sentence_tells_inert_small_saturated_and_moving_apart() -> None:
    inert = rnd_sentence(_data(-0.9, -0.2, 0.4, **{"nominal@0.5": _case(-0.9, rnd=0.01, p90=0.02)}))
    assert "0.050 on the plane at 1 m/s against 0.010 at the training speed (`nominal@0.5`)" in inert
    assert inert.endswith("inert: its 90th percentile stays below 0.1 in every case, beta is the band's")
    small = _data(-0.9, -0.2, 0.4)
    small["cases"]["uneven"].update(beta_rnd=0.12, beta_rnd_p90=0.21, beta_rnd_above_half=0.01)
    assert rnd_sentence(small).endswith(
        "small: above 0.5 on fewer than 5% of the states of every case, its 90th percentile at most 0.210"
    )
    saturated = _data(0.1, 0.1, 0.1)
    for case in saturated["cases"].values():
        case.update(beta_rnd=0.97, beta_rnd_p90=1.0, beta_rnd_above_half=1.0)
    assert "saturated: its mean is above 0.9 in every case" in rnd_sentence(saturated)
    moving = _data(-0.9, -0.2, 0.4)
    moving["cases"]["uneven"].update(beta_rnd=0.6, beta_rnd_p90=0.9, beta_rnd_above_half=0.55)
    assert rnd_sentence(moving).endswith(
        "it moves beta: above 0.5 on 55% of the states of `uneven`, against 0% in `nominal@1`"
    )
    without = {**moving, "band": {**moving["band"], "use_rnd": False}}
    assert rnd_sentence(without) == "no RND part (beta_RND = 0)"


def test_the_section_shows_measured_agents_and_the_command_for_the_others(tmp_path: Path) -> None:
    (tmp_path / "p.yml").write_text("Zerith1-v0: {}\n")
    entries = [
        ("huri-s0", "huri", "huri/Zerith1-v0_1", 1000),
        ("no-rnd-s0", "huri-no-rnd", "huri-no-rnd/Zerith1-v0_1", 1000),
        ("ppo-s0", "huri-baseline", "ppo/Zerith1-v0_1", 1000),
        ("cvar05-s0", "huri-cvar0.5", "cvar/Zerith1-v0_1", 1000),
        ("huri-s0-long", "huri", "huri/Zerith1-v0_1", 5000),
    ]
    queue = {
        "entries": [
            {"name": n, "method": m, "run": r, "steps": s, "seed": 0, "protocol": "robust", "conf": "p.yml"}
            for n, m, r, s in entries
        ]
    }  # fmt: skip
    (tmp_path / "campaign.yml").write_text(yaml.safe_dump(queue))
    for run in ("huri/Zerith1-v0_1", "huri-no-rnd/Zerith1-v0_1"):
        (tmp_path / run / ENV).mkdir(parents=True)
        (tmp_path / run / ENV / "state.json").write_text(json.dumps({"timesteps": 1200}))
    measured = tmp_path / "huri" / "Zerith1-v0_1" / "evaluations"
    measured.mkdir()
    (measured / "1200-risk_levels.json").write_text(json.dumps(_data(-0.9, -0.2, 0.4)))
    lines = risk_levels_section(load_queue(tmp_path / "campaign.yml"))
    page = "\n".join(lines)
    assert lines[0].startswith("## 6b.")
    row = next(line for line in lines if "`sudden-centroid`" in line)
    cells = [cell.strip() for cell in row.strip("|").split("|")]
    assert cells == [
        "huri-s0 @ 0.0M, absolute band [0.300, 0.700]", "`sudden-centroid`", "0.500", "0.300", "0.200",
        "-0.200", "0.050", "0.080", "0.250", "1.000",
    ]  # fmt: skip
    rows = [line for line in lines if line.startswith("| huri-s0 ")]
    assert [row.split("|")[2].strip() for row in rows] == ["`nominal@1`", "`sudden-centroid`", "`uneven`"]
    assert "- huri-s0 at 0.0M: mean beta +0.400 on uneven ground" in page and "order holds" in page
    assert "over the 1 agent measured: 0.50-0.50 on the plane, 0.50-0.50 under pushes" in page
    command = "`python -m study.scripts.risk_levels"
    assert f"- no-rnd-s0 (huri-no-rnd): {command} {tmp_path / 'huri-no-rnd' / 'Zerith1-v0_1'}" in page
    assert "--steps 1000`" in page
    assert "Not trained to their steps yet" in page and "huri-s0-long." in page  # 1200 < 5000: not its file
    assert "ppo-s0" not in page and "cvar05-s0" not in page  # no IQR band: not of the family


def test_the_family_is_every_method_reading_the_iqr_band() -> None:
    from sb3_huri.huri import METHODS

    family = [method for method in METHODS if risk_family(method)]
    assert family == ["huri-no-rnd", "huri", "huri-percentile", "huri-cvar"]


def test_the_results_page_holds_the_section(tmp_path: Path) -> None:
    from study.results import write_results

    (tmp_path / "preset.yml").write_text("Zerith1-v0: {}\n")
    entry = {"name": "huri-s0", "method": "huri", "run": "huri/Zerith1-v0_1", "steps": 1000, "seed": 0}
    queue = {"entries": [{**entry, "protocol": "robust", "conf": "preset.yml"}]}
    (tmp_path / "campaign.yml").write_text(yaml.safe_dump(queue))
    page = write_results(tmp_path / "campaign.yml", tmp_path / "docs" / "results.md").read_text()
    assert page.index("## 6. Risk") < page.index("## 6b. Risk levels") < page.index("## 9.")
    assert "Not trained to their steps yet" in page and "huri-s0." in page


def test_the_script_answers_help(monkeypatch, capsys) -> None:
    monkeypatch.setattr(sys, "argv", ["risk_levels.py", "--help"])
    with pytest.raises(SystemExit) as stop:
        runpy.run_module("study.scripts.risk_levels", run_name="__main__")
    assert stop.value.code == 0
    assert capsys.readouterr().out.startswith("usage:")
