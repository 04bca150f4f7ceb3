"""How good a baseline each agent's value is (``study.analyses.value_baseline``).

Its lambda = 1 returns are checked against the GAE written in the tests (``huri_helpers.gae`` at lambda = 1,
plus the value), its count of steps to a fall against a hand-made episode, and the measurement end to end
on run folders of the robust recipe shrunk to seconds (HuRi, huri-neutral and PPO), in the campaign's
analyses too.
"""

from __future__ import annotations

import runpy
import sys
from pathlib import Path

import numpy as np
import pytest
from huri_helpers import ROOT, gae, tiny_robust_preset

from sb3_huri.runner.training import RunRequest, TrainingOptions, train_run
from sb3_huri.zoo import read_preset
from study.analyses.value_baseline import (
    lambda_one_returns,
    measure_value_baseline,
    measured_record,
    steps_to_fall,
    value_baseline_path,
)

STEPS = 64


def test_lambda_one_returns_are_gae_at_lambda_one_plus_the_value() -> None:
    rng = np.random.default_rng(0)
    rewards, values = rng.normal(size=(30, 3)), rng.normal(size=(30, 3))
    starts = (rng.random((30, 3)) < 0.1).astype(float)
    last_values, last_dones = rng.normal(size=3), np.array([0.0, 1.0, 0.0])
    expected = gae(rewards, values, starts, last_values, last_dones, 0.97, 1.0) + values
    returns = lambda_one_returns(rewards, starts, last_values, last_dones, 0.97)
    np.testing.assert_allclose(returns, expected, rtol=1e-10, atol=1e-10)


def test_steps_to_a_fall_count_within_an_episode_ending_in_a_fall_only() -> None:
    # Robot 0: an episode falls at step 3, the next one times out at step 6, the last runs past the end.
    # Robot 1: falls at step 7, the array's last step.
    dones = np.zeros((8, 2), dtype=bool)
    falls = np.zeros((8, 2), dtype=bool)
    dones[3, 0] = falls[3, 0] = True
    dones[6, 0] = True
    dones[7, 1] = falls[7, 1] = True
    remaining = steps_to_fall(dones, falls)
    np.testing.assert_array_equal(remaining[:, 0], [3, 2, 1, 0, np.inf, np.inf, np.inf, np.inf])
    np.testing.assert_array_equal(remaining[:, 1], [7, 6, 5, 4, 3, 2, 1, 0])


@pytest.fixture(scope="module")
def runs(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """HuRi, huri-neutral and PPO run folders of the tiny robust preset, trained 64 steps in 420-step episodes
    (the robust scenario starts episodes up to 400 steps into its force cycle)."""
    folder = tmp_path_factory.mktemp("value_baseline")
    preset = read_preset("Zerith1-v0", tiny_robust_preset(folder))
    preset["env_kwargs"]["episode_steps"] = 420
    options = TrainingOptions(checkpoint_freq=10_000, workers=0, verbose=0)
    found = {}
    for method in ("huri", "huri-neutral", "huri-baseline"):
        found[method] = folder / method / "Zerith1-v0_1"
        assert train_run(RunRequest(found[method], preset, method, 0, until=STEPS), options) == STEPS
    return found


def test_a_quantile_critic_is_measured_on_both_values_and_its_risk_before_falls(runs) -> None:
    path = measure_value_baseline(runs["huri"], warmup=1, rollouts=3)
    assert path == value_baseline_path(runs["huri"], STEPS)
    record = measured_record(path)
    assert record is not None and record["method"] == "huri" and record["steps"] == STEPS
    assert set(record["explained_variance"]) == {"value", "atom_mean"}
    assert len(record["per_rollout"]) == 3
    for explained in [record["explained_variance"], *record["per_rollout"]]:
        assert all(np.isfinite(value) and value <= 1.0 for value in explained.values())
    assert (
        record["settings"]["robots"] * record["settings"]["rollout_steps"] * 3 > record["before_fall_states"]
    )
    if record["falls"]:
        assert record["before_fall_states"] >= record["falls"] and -1.0 <= record["risk_before_fall"] <= 1.0
    assert -2.0 <= record["risk_elsewhere"] <= 2.0  # beta_IQR in [-1, 1] plus tanh(RND) in [0, 1)


def test_a_risk_neutral_critic_s_value_is_its_atom_mean_at_risk_level_zero(runs) -> None:
    record = measured_record(measure_value_baseline(runs["huri-neutral"], warmup=1, rollouts=2))
    assert record is not None and record["method"] == "huri-neutral"
    explained = record["explained_variance"]
    assert set(explained) == {"value", "atom_mean"}
    assert explained["value"] == pytest.approx(explained["atom_mean"], abs=1e-6)
    assert record["risk_elsewhere"] == 0.0
    assert record["risk_before_fall"] in (None, 0.0)


def test_ppo_is_measured_on_its_value_alone_and_has_no_risk_level(runs, monkeypatch, capsys) -> None:
    script = ROOT / "study" / "scripts" / "value_baseline.py"
    monkeypatch.setattr(
        sys, "argv", [str(script), str(runs["huri-baseline"]), "--warmup", "0", "--rollouts", "2"]
    )
    runpy.run_path(str(script), run_name="__main__")
    record = measured_record(value_baseline_path(runs["huri-baseline"], STEPS))
    assert record is not None and set(record["explained_variance"]) == {"value"}
    assert record["risk_before_fall"] is None and record["risk_elsewhere"] is None
    assert "explained variance of the lambda = 1 returns by value" in capsys.readouterr().out
