"""How far an agent's risk distortion moves its advantages (``study.analyses.advantages``,
``study/scripts/advantages.py``) and its section of the results page.

The advantages under a constant risk level are checked against a GAE written here from the rollout's own
rewards, episode starts and atoms with Wang weights from scipy's normal distribution; the measurement runs
on real run folders trained a few rollouts with the robust recipe shrunk to seconds.
"""

from __future__ import annotations

import json
import runpy
import sys
from pathlib import Path

import numpy as np
import pytest
import torch as th
import yaml
from huri_helpers import gae, tiny_robust_preset
from scipy import stats

from sb3_huri.experiments.errors import ExperimentError
from sb3_huri.runner.training import RunRequest, TrainingOptions, train_run
from sb3_huri.zoo import read_preset
from study.analyses.advantages import (
    advantages_path,
    constant_risk_advantages,
    measure_advantages,
    measured_record,
    signal_change,
    summary,
)
from study.results import write_results

STEPS = 128
EPISODE_STEPS = 420  # the robust scenario starts episodes up to 400 steps into its force cycle


@pytest.fixture(scope="module")
def runs(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """Run folders of the tiny robust preset trained 128 steps with 420-step episodes and a curriculum over
    256 steps: HuRi with the percentile band (a checkpoint kept at 64 steps), CVaR 0.5 (one fixed risk
    level) and PPO."""
    folder = tmp_path_factory.mktemp("advantages")
    preset = read_preset("Zerith1-v0", tiny_robust_preset(folder))
    preset["env_kwargs"]["episode_steps"] = EPISODE_STEPS
    preset["callback"][1]["zerith_gym.sb3.callbacks.RandomizationCurriculum"]["steps"] = 256
    options = TrainingOptions(checkpoint_freq=10_000, keep_every=64, workers=0, verbose=0)
    found = {}
    for method in ("huri-percentile", "huri-cvar0.5", "huri-baseline"):
        found[method] = folder / method / "Zerith1-v0_1"
        assert train_run(RunRequest(found[method], preset, method, 0, until=STEPS), options) == STEPS
    return found


def _wang_weights(beta: float, n: int) -> np.ndarray:
    levels = stats.norm.cdf(stats.norm.ppf(np.linspace(0.0, 1.0, n + 1)) + beta)
    return np.diff(levels)


def _collected(run: Path) -> tuple[object, object, np.ndarray, np.ndarray]:
    """The run's model after one rollout of 4 robots in 12-step episodes (time-outs inside the rollout):
    model, env, the sorted atoms of the states after the rollout and whether each robot's last step ended."""
    from stable_baselines3.common.callbacks import CallbackList
    from stable_baselines3.common.logger import configure

    import zerith_gym
    from sb3_huri.runner.folder import load_checkpoint

    model, _ = load_checkpoint(run / "Zerith1-v0.zip", None)
    env = zerith_gym.make_vec_env(4, seed=5, workers=0, episode_steps=12)
    model.set_env(env)
    model.set_logger(configure(None, []))
    model._last_obs, model._last_episode_starts = env.reset(), np.ones(4, dtype=bool)
    callback = CallbackList([])
    callback.init_callback(model)
    model.collect_rollouts(env, callback, model.rollout_buffer, model.n_steps)
    assert model.rollout_buffer.has_time_outs
    with th.no_grad():
        last = th.sort(model.policy.predict_values(model.policy.obs_to_tensor(model._last_obs)[0]), -1).values
    return model, env, last.numpy(), model._last_episode_starts.astype(np.float32)


def test_constant_risk_advantages_are_gae_on_that_levels_value(runs) -> None:
    model, env, last_atoms, dones = _collected(runs["huri-percentile"])
    buffer = model.rollout_buffer
    own_weights = buffer.distortion_weights.copy()

    advantages = constant_risk_advantages(model, last_atoms, dones, 0.7)

    weights = _wang_weights(0.7, buffer.atoms.shape[-1])
    rewards = buffer.rewards + buffer.gamma * (buffer.bootstrap_atoms @ weights)  # time-outs bootstrapped
    expected = gae(
        rewards, buffer.atoms @ weights, buffer.episode_starts, last_atoms @ weights, dones, buffer.gamma,
        buffer.gae_lambda,
    )  # fmt: skip
    np.testing.assert_allclose(advantages, expected, rtol=1e-4, atol=1e-5)
    np.testing.assert_array_equal(buffer.distortion_weights, own_weights)  # the agent's own levels restored
    env.close()


def test_a_fixed_level_recomputed_is_the_algorithms_own_advantages(runs) -> None:
    """CVaR 0.5 gives every state the same level: the recomputation at 0.5 must be what the algorithm
    computed while collecting, time-outs and the last state included."""
    model, env, last_atoms, dones = _collected(runs["huri-cvar0.5"])
    own = model.rollout_buffer.advantages.copy()
    np.testing.assert_allclose(constant_risk_advantages(model, last_atoms, dones, 0.5), own, atol=1e-5)
    assert not np.allclose(constant_risk_advantages(model, last_atoms, dones, 1.0), own, atol=1e-3)
    env.close()


def test_signal_change_of_the_same_the_opposite_and_a_noisy_signal() -> None:
    signal = np.random.default_rng(0).normal(size=1000)
    assert signal_change(signal, 3.0 * signal) == pytest.approx(
        {"correlation": 1.0, "sign_changes": 0.0, "weighted_sign_changes": 0.0}, abs=1e-9
    )
    assert signal_change(signal, -signal) == pytest.approx(
        {"correlation": -1.0, "sign_changes": 1.0, "weighted_sign_changes": 1.0}
    )
    noisy = signal + np.random.default_rng(1).normal(size=1000)
    change = signal_change(signal, noisy)
    assert change["correlation"] == pytest.approx(stats.pearsonr(signal, noisy)[0])
    turned = (signal > 0) != (noisy > 0)
    assert change["sign_changes"] == turned.mean()
    weighted = sum(abs(a) for a, t in zip(signal, turned, strict=True) if t) / sum(abs(a) for a in signal)
    assert change["weighted_sign_changes"] == pytest.approx(weighted)
    assert change["weighted_sign_changes"] < change["sign_changes"]  # the turned ones are the small ones
    with pytest.raises(ExperimentError, match="all equal"):
        signal_change(signal, np.ones(1000))


def test_a_run_is_measured_on_its_own_training_rollouts(runs) -> None:
    from sb3_huri.runner.state import RunState
    from zerith_gym.sb3.callbacks import RandomizationCurriculum

    run = runs["huri-percentile"]
    path = measure_advantages(run)
    assert path == advantages_path(run, STEPS) and measured_record(path) is not None
    record = json.loads(path.read_text())
    assert record["method"] == "huri-percentile" and record["steps"] == STEPS
    # One 420-step episode of 16-step rollouts each: 27 of warm-up, 27 measured.
    assert record["settings"] == {
        "seed": 2000,
        "warmup": 27,
        "rollouts": 27,
        "robots": 4,
        "rollout_steps": 16,
    }
    assert record["curriculum"] == {"stage": RunState.read(run).curriculum_stage, "stages": 4,
                                    "scale": RunState.read(run).curriculum_stage / 4}  # fmt: skip
    assert record["band"]["reading"] == "percentile" and len(record["rollouts"]) == 27
    first = record["rollouts"][0]
    assert first["neutral"]["level"] == 0.0 and first["risk_sd"] > 0.0  # the band sets levels per state
    assert first["constant"]["level"] == pytest.approx(first["risk_mean"])
    # Each TD error at its own step's level leaves out the jumps between levels: a signal of its own.
    assert first["other_td_level"]["level"] == "step" and first["other_td_level"]["correlation"] < 1.0
    assert set(first["other_td_level"]["neutral"]) == {"correlation", "sign_changes", "weighted_sign_changes"}
    means = summary(record)
    values = [r["neutral"]["sign_changes"] for r in record["rollouts"]]
    assert means["neutral_sign_changes"] == pytest.approx(np.mean(values))
    assert means["neutral_sign_changes_range"] == (min(values), max(values))

    # The checkpoint kept at 64 steps is measured at the curriculum's scheduled stage for 64 steps.
    kept = json.loads(measure_advantages(run, steps=64, warmup=0, rollouts=1).read_text())
    expected = RandomizationCurriculum(steps=256, stages=4).scheduled_stage(64)
    assert kept["model"] == "checkpoints/rl_model_64_steps.zip" and kept["curriculum"]["stage"] == expected

    # CVaR 0.5 is one fixed level for every state: its own advantages are the constant level's.
    fixed = json.loads(measure_advantages(runs["huri-cvar0.5"], warmup=0, rollouts=1).read_text())
    (rollout,) = fixed["rollouts"]
    assert rollout["risk_sd"] == 0.0 and rollout["constant"]["level"] == pytest.approx(0.5)
    assert (
        rollout["constant"]["correlation"] == pytest.approx(1.0) and rollout["constant"]["sign_changes"] == 0
    )
    assert rollout["neutral"]["level"] == 1.0 and rollout["neutral"]["correlation"] < 1.0
    # With one level for every state the two readings of a TD error's levels are the same.
    assert rollout["other_td_level"]["correlation"] == pytest.approx(1.0)
    assert rollout["other_td_level"]["weighted_sign_changes"] == pytest.approx(0.0, abs=1e-6)

    with pytest.raises(ExperimentError, match="no quantile critic"):
        measure_advantages(runs["huri-baseline"])


def test_a_file_without_a_measure_is_measured_again(runs, tmp_path) -> None:
    path = measure_advantages(runs["huri-cvar0.5"], warmup=0, rollouts=1)
    record = json.loads(path.read_text())
    for rollout in record["rollouts"]:
        del rollout["neutral"]["weighted_sign_changes"]
    stale = tmp_path / "stale.json"
    stale.write_text(json.dumps(record))
    assert measured_record(stale) is None and measured_record(tmp_path / "none.json") is None
    assert measured_record(stale, shown=True) is None
    # A file written before the TD reading's comparator existed is measured again, but still shown.
    record = json.loads(path.read_text())
    for rollout in record["rollouts"]:
        del rollout["other_td_level"]["neutral"]
    stale.write_text(json.dumps(record))
    assert measured_record(stale) is None  # the other reading against the neutral level came later still
    for rollout in record["rollouts"]:
        del rollout["other_td_level"]
    stale.write_text(json.dumps(record))
    assert measured_record(stale) is None and measured_record(stale, shown=True) == record
    assert "other_td_level_correlation" not in summary(record) and "neutral_correlation" in summary(record)


def test_the_results_page_shows_each_measured_agent_and_the_command_for_the_others(runs, tmp_path) -> None:
    measure_advantages(runs["huri-percentile"], warmup=0, rollouts=2)
    advantages_path(runs["huri-cvar0.5"], STEPS).unlink(missing_ok=True)
    root = runs["huri-percentile"].parent.parent
    entries = []
    for method, run in runs.items():
        name = f"{method}-s0"
        entries.append({"name": name, "protocol": "robust", "method": method, "seed": 0, "steps": STEPS,
                        "run": str(run.relative_to(root)), "conf": "tiny.yml"})  # fmt: skip
        (run / "evaluations").mkdir(exist_ok=True)
        evaluation = {"entry": name, "steps": STEPS, "settings": {"episodes": 1}, "cases": {}}
        (run / "evaluations" / f"{STEPS}.json").write_text(json.dumps(evaluation))
    (root / "campaign.yml").write_text(yaml.safe_dump({"entries": entries}))
    page = write_results(root / "campaign.yml", tmp_path / "results.md").read_text()
    start = page.index("## 6c.")
    section = page[start : page.index("\n## ", start)]
    record = json.loads(advantages_path(runs["huri-percentile"], STEPS).read_text())
    means = summary(record)
    row = next(line for line in section.splitlines() if line.startswith("| huri-percentile-s0 @"))
    cells = [cell.strip() for cell in row.strip("|").split("|")]
    assert cells[2:5] == [f"{2 * 4 * 16:,}", f"{record['curriculum']['scale']:g}",
                          f"{means['risk_mean']:+.2f} ({means['risk_sd']:.2f})"]  # fmt: skip
    keys = ("correlation", "sign_changes", "weighted_sign_changes")
    for cell, name in zip(cells[5:], ("neutral", "constant", "other_td_level"), strict=True):
        assert cell.startswith(" / ".join(f"{means[f'{name}_{key}']:.3f}" for key in keys))
    assert cells[7].endswith(f"({means['other_td_level_neutral_weighted_sign_changes']:.3f})")
    run = runs["huri-cvar0.5"]
    assert f"huri-cvar0.5-s0: `python -m study.scripts.advantages {run} --steps {STEPS}`" in section
    assert "huri-baseline-s0" not in section  # PPO has no distortion


def test_the_script_answers_help(monkeypatch, capsys) -> None:
    monkeypatch.setattr(sys, "argv", ["advantages.py", "--help"])
    with pytest.raises(SystemExit) as stop:
        runpy.run_module("study.scripts.advantages", run_name="__main__")
    assert stop.value.code == 0 and capsys.readouterr().out.startswith("usage:")
