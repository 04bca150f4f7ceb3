"""The grid on standard Gymnasium tasks: the presets of the five-seed test, the statistics of its report
(IQM, stratified bootstrap, probability of improvement) against independent computations, and a tiny grid
on ``InvertedPendulum-v5`` that trains, resumes, evaluates the true return and reports.
"""

from __future__ import annotations

import itertools
import json
import math
import shutil
from pathlib import Path

import numpy as np
import pytest
import yaml
from scipy import stats

from sb3_huri.experiments import EvalSettings, ExperimentError, run_experiment, write_report
from sb3_huri.experiments.grid.layout import env_kind, read_status, run_folder
from sb3_huri.experiments.grid.standard import RETURN_CASE, evaluate_checkpoint
from sb3_huri.experiments.statistics import (
    improvement_interval,
    iqm,
    iqm_interval,
    mean_ci,
    probability_of_improvement,
    stratified_bootstrap,
)
from sb3_huri.runner.curve import read_curve
from sb3_huri.runner.folder import load_run
from sb3_huri.runner.record import record_path
from sb3_huri.runner.state import RunState

REPO = Path(__file__).resolve().parents[1]


# ------------------------------------------------------------------------------------------------ presets
def test_the_five_seed_presets_are_the_ppo_papers_settings_with_sb3s_ppo_defaults() -> None:
    import inspect

    from stable_baselines3 import PPO

    presets = yaml.safe_load((REPO / "hyperparams" / "huri.yml").read_text())
    ppo_paper = {
        "n_envs": 1, "n_steps": 2048, "batch_size": 64, "n_epochs": 10, "learning_rate": 3e-4, "gamma": 0.99,
        "gae_lambda": 0.95, "clip_range": 0.2, "ent_coef": 0.0, "normalize": True, "n_timesteps": 1e6,
        "policy": "MlpPolicy", "policy_kwargs": "dict(net_arch=[64, 64], activation_fn=nn.Tanh)",
    }  # fmt: skip
    defaults = inspect.signature(PPO.__init__).parameters
    sb3 = {name: defaults[name].default for name in ("vf_coef", "max_grad_norm")}
    assert sb3 == {"vf_coef": 0.5, "max_grad_norm": 0.5}
    # Hopper-v5 keeps the coefficients it was measured with, HuRiPPO's defaults then
    assert presets["Hopper-v5"] == {**ppo_paper, "vf_coef": 1.0, "max_grad_norm": 1.0}
    for env in ("HalfCheetah-v5", "Walker2d-v5"):
        assert presets[env] == {**ppo_paper, **sb3}
        assert "method" not in presets[env]  # the methods differ in what they are, nothing else
        assert env_kind(env) == "standard"
    assert env_kind("Zerith1-v0") == "zerith"
    with pytest.raises(ExperimentError, match="its Zerith protocol is Zerith1-v0's"):
        env_kind("Go2Like-v0")
    with pytest.raises(ExperimentError, match="unknown env 'NoSuchEnv-v0'"):
        env_kind("NoSuchEnv-v0")


# --------------------------------------------------------------------------------------------- statistics
def test_iqm_is_the_mean_of_the_middle_half() -> None:
    rng = np.random.default_rng(1)
    for n in range(1, 14):
        values = rng.normal(size=n)
        assert iqm(values) == pytest.approx(stats.trim_mean(values, 0.25))  # rliable's IQM
    values = [7.0, -3.0, 100.0, 2.0, 4.0, 1.0, 5.0, -50.0]  # 8 values: the middle four are 1, 2, 4, 5
    assert iqm(values) == 3.0
    assert iqm([1.0, 2.0, 3.0, 4.0, 1000.0]) == 3.0  # five seeds: the middle three
    with pytest.raises(ValueError, match="no values"):
        iqm([])


def test_probability_of_improvement_counts_every_pair_ties_half() -> None:
    rng = np.random.default_rng(2)
    for n, m in ((5, 5), (3, 7), (1, 4)):
        x, y = rng.integers(0, 4, n).astype(float), rng.integers(0, 4, m).astype(float)  # many ties
        brute = sum(1.0 if a > b else 0.5 if a == b else 0.0 for a, b in itertools.product(x, y)) / (n * m)
        assert probability_of_improvement(x, y) == pytest.approx(brute)
        assert probability_of_improvement(x, y) == pytest.approx(stats.mannwhitneyu(x, y).statistic / (n * m))
        assert probability_of_improvement(x, y) + probability_of_improvement(y, x) == pytest.approx(1.0)
    assert probability_of_improvement([2.0, 3.0], [0.0, 1.0]) == 1.0
    assert probability_of_improvement([1.0, 1.0], [1.0]) == 0.5


def test_stratified_bootstrap_resamples_seeds_within_each_task() -> None:
    # Two tasks of constant scores: any resample within the tasks keeps the pooled mean at 0.5 exactly,
    # where a bootstrap pooling the tasks' seeds would move it.
    strata = [[np.zeros(5)], [np.ones(5)]]
    pooled = stratified_bootstrap(strata, lambda s: float(np.mean(np.concatenate([s[0][0], s[1][0]]))))
    assert pooled == (0.5, 0.5)
    # One stratum: the percentile interval of SciPy's bootstrap (another generator: agreement to noise).
    values = np.random.default_rng(3).normal(10.0, 2.0, size=20)
    ours = stratified_bootstrap([[values]], lambda s: float(np.mean(s[0][0])), resamples=20_000)
    scipy_ci = stats.bootstrap((values,), np.mean, n_resamples=20_000, method="percentile", random_state=4)
    width = scipy_ci.confidence_interval.high - scipy_ci.confidence_interval.low
    assert ours == pytest.approx(tuple(scipy_ci.confidence_interval), abs=0.05 * width)
    # Reported intervals repeat: the generator is seeded.
    assert iqm_interval(values) == iqm_interval(values)
    value, low, high = iqm_interval(values)
    assert value == pytest.approx(stats.trim_mean(values, 0.25)) and low < value < high


def test_improvement_interval_averages_the_tasks() -> None:
    # Task A: the method beats every PPO seed; task B: it loses to every one. Resampling within each task
    # keeps both facts, so the average is 0.5 in every resample.
    pairs = [([5.0, 6.0, 7.0], [1.0, 2.0, 3.0]), ([0.0, 0.5, 1.0], [2.0, 3.0, 4.0])]
    assert improvement_interval(pairs) == (0.5, 0.5, 0.5)
    x, y = [1.0, 4.0, 6.0, 2.0, 9.0], [3.0, 5.0, 4.0, 0.0, 8.0]
    value, low, high = improvement_interval([(x, y)])
    brute = sum((a > b) + 0.5 * (a == b) for a in x for b in y) / 25
    assert value == pytest.approx(brute) and 0.0 <= low <= value <= high <= 1.0


# ------------------------------------------------------------------------------------------------- grid
ENV = "InvertedPendulum-v5"
TINY_PRESET = f"""\
{ENV}:
  n_envs: 1
  n_timesteps: 1024
  policy: MlpPolicy
  normalize: true
  n_steps: 64
  batch_size: 32
  n_epochs: 2
  policy_kwargs: "dict(net_arch=[16, 16], activation_fn=nn.Tanh)"
"""
EVAL = EvalSettings(episodes=2, seed=7)
GRID = (["huri-baseline", "huri"], [0, 1])


@pytest.fixture(scope="module")
def grid(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The grid trained to 256 steps, then the same command with 512: every run resumes."""
    conf = tmp_path_factory.mktemp("conf") / "tiny.yml"
    conf.write_text(TINY_PRESET)
    out = tmp_path_factory.mktemp("standard") / "exp"
    for steps in (256, 512):
        outcomes = run_experiment(
            out, ENV, *GRID, steps, EVAL, conf=conf, checkpoint_freq=128, poll_seconds=0.5, echo=print
        )
        done = sorted((o.method, o.seed) for o in outcomes if o.state == "done")
        assert done == sorted(itertools.product(*GRID)), outcomes
    return out


def test_the_grid_trains_resumes_and_evaluates_a_standard_task(grid: Path) -> None:
    for method, seed in itertools.product(*GRID):
        folder = run_folder(grid, ENV, method, seed)
        status = read_status(folder, method, seed, ENV)
        assert status.state == "done" and status.trained_to == 512 and status.resumed_from == [256]
        model, normalizer = load_run(folder, ENV)  # RL Zoo's layout: <env>.zip, <env>/vecnormalize.pkl
        assert model.num_timesteps == 512 and model.method == method and normalizer is not None
        state = RunState.read(folder, ENV)
        assert [(s["from_timesteps"], s["to_timesteps"]) for s in state.sessions] == [(0, 256), (256, 512)]
        assert state.wall_s > 0 and all(s["hardware"] for s in state.sessions)
        assert [row["timesteps"] for row in read_curve(folder)] == list(range(64, 513, 64))
        record = json.loads(record_path(folder, 512).read_text())
        assert (record["method"], record["seed"], record["steps"]) == (method, seed, 512)
        case = record["cases"][RETURN_CASE]
        assert len(case["returns"]) == len(case["lengths"]) == 2
        # InvertedPendulum-v5 pays 1 per step but the terminating one: the true, unnormalized return.
        for episode_return, length in zip(case["returns"], case["lengths"], strict=True):
            assert episode_return == (length if length == 1000 else length - 1)
        assert case["mean_return"] == pytest.approx(np.mean(case["returns"]))
    # The evaluation is deterministic and leaves the normalizer as it was: the same returns again.
    folder = run_folder(grid, ENV, "huri", 1)
    before = (folder / ENV / "vecnormalize.pkl").read_bytes()
    again = evaluate_checkpoint(folder, ENV, EVAL.episodes, EVAL.seed)["cases"][RETURN_CASE]
    assert (
        again["returns"] == json.loads(record_path(folder, 512).read_text())["cases"][RETURN_CASE]["returns"]
    )
    assert (folder / ENV / "vecnormalize.pkl").read_bytes() == before


def _returns(out: Path, method: str) -> list[float]:
    return [
        json.loads(record_path(run_folder(out, ENV, method, seed), 512).read_text())["cases"][RETURN_CASE][
            "mean_return"
        ]
        for seed in GRID[1]
    ]


def test_the_report_gives_means_iqms_and_the_probability_of_beating_ppo(grid: Path) -> None:
    text = write_report(grid).read_text()
    assert f"## {ENV}" in text and "Student's t" in text and "stratified by task" in text
    assert "| method | seeds | mean ± 95% CI (t) | IQM [95% CI] | P(> PPO) [95% CI] | per seed |" in text
    huri, ppo = _returns(grid, "huri"), _returns(grid, "huri-baseline")
    mean, half, _ = mean_ci(huri)
    row = next(line for line in text.splitlines() if line.startswith("| `huri` | 2 |"))
    cell = f"{mean:.1f} ± {half:.1f}" if math.isfinite(half) else f"{mean:.1f}"
    assert cell in row and f"0: {huri[0]:.1f}, 1: {huri[1]:.1f}" in row
    assert f"{probability_of_improvement(huri, ppo):.2f} [" in row
    assert "## Runs: InvertedPendulum-v5" in text and "(resumed from 256)" in text and "cores" in text
    # A folder of tasks' folders: every task, and P(> PPO) across them.
    tasks = grid.parent / "tasks"
    for name in ("a", "b"):
        shutil.copytree(grid, tasks / name)
    combined = write_report(tasks).read_text()
    assert combined.count(f"## {ENV}") == 2 and "## Across tasks" in combined
    tail = combined.split("## Across tasks")[1].splitlines()
    across = next(line for line in tail if line.startswith("| `huri` | 2 |"))
    assert f"| {probability_of_improvement(huri, ppo):.2f} [" in across
