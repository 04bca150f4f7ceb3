"""``python -m sb3_huri.experiments``: grids on the local pool and on Ray, real interruptions and resuming,
the report, and the errors for bad grids and folders.

Every run here is tiny (2 robots, a preset with 16-unit networks, a few hundred steps, evaluation episodes of
20 steps) so that the grid's machinery, not the learning, is what is tested.
"""

from __future__ import annotations

import json
import math
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from sb3_huri.experiments import EvalSettings, ExperimentError, run_experiment, write_report
from sb3_huri.experiments.__main__ import main
from sb3_huri.experiments.grid.layout import Settings, open_experiment, read_status, run_folder
from sb3_huri.experiments.grid.report import _ordering
from sb3_huri.experiments.statistics import mean_ci, paired_difference_interval, wilson_interval
from sb3_huri.runner.curve import read_curve
from sb3_huri.runner.evaluation import PROTOCOL, RISK_CASES
from sb3_huri.runner.files import write_json
from sb3_huri.runner.folder import load_run, next_run_folder
from sb3_huri.runner.record import record_path, trace_path
from sb3_huri.runner.state import RunState

ENV = "Zerith1-v0"
TINY_PRESET = """\
Zerith1-v0:
  n_envs: 2
  n_timesteps: 512
  policy: MultiInputPolicy
  normalize: "dict(norm_obs=True, norm_reward=True)"
  callback:
    - zerith_gym.sb3.callbacks.RewardTermsLogger
    - zerith_gym.sb3.callbacks.RandomizationCurriculum:
        steps: 256
        stages: 2
  env_kwargs:
    episode_steps: 40
  n_steps: 32
  n_minibatches: 2
  n_epochs: 1
  n_quantiles: 8
  policy_kwargs: "dict(net_arch=[16, 16])"
"""
TINY_EVAL = EvalSettings(episodes=2, episode_steps=20)


@pytest.fixture(scope="module")
def conf(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("conf") / "tiny.yml"
    path.write_text(TINY_PRESET)
    return path


def status_of(out: Path, method: str, seed: int):
    return read_status(run_folder(out, ENV, method, seed), method, seed, ENV)


def cli(*argv: str) -> list[str]:
    return [sys.executable, "-m", "sb3_huri.experiments", *argv]


# ------------------------------------------------------------------------------------------------ grids
@pytest.fixture(scope="module")
def local_grid(conf: Path, tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, list]:
    out = tmp_path_factory.mktemp("grid") / "exp"
    lines: list[str] = []
    outcomes = run_experiment(
        out,
        ENV,
        ["huri", "huri-baseline"],
        [0, 1],
        256,
        TINY_EVAL,
        conf=conf,
        checkpoint_freq=128,
        poll_seconds=0.5,
        echo=lines.append,
    )
    return out, outcomes, lines


def test_local_grid_trains_and_evaluates_every_run_in_rl_zoo_layout(local_grid) -> None:
    out, outcomes, lines = local_grid
    assert sorted((o.method, o.seed, o.state) for o in outcomes) == [
        ("huri", 0, "done"),
        ("huri", 1, "done"),
        ("huri-baseline", 0, "done"),
        ("huri-baseline", 1, "done"),
    ]
    assert any("done, 256 steps" in line for line in lines)
    for method in ("huri", "huri-baseline"):
        for seed in (0, 1):
            folder = run_folder(out, ENV, method, seed)
            assert folder == out / method / f"{ENV}_{seed + 1}"
            status = status_of(out, method, seed)
            assert status.state == "done" and status.trained_to == 256 and status.steps == 256
            assert status.resumed_from == [] and status.eval_done == len(PROTOCOL)
            model, normalizer = load_run(folder, ENV)  # RL Zoo's layout, as `rl_zoo3 enjoy` reads it
            assert model.num_timesteps == 256 and normalizer is not None
            assert model.method == method
            assert model.seed == seed
            # The evaluation record the campaign writes too: the checkpoint's, with each robot's outcome.
            evaluation = json.loads(record_path(folder, 256).read_text())
            assert (evaluation["method"], evaluation["seed"], evaluation["steps"]) == (method, seed, 256)
            assert sorted(evaluation["cases"]) == sorted(PROTOCOL)
            for metrics in evaluation["cases"].values():
                assert 0.0 <= metrics["survive"] <= 1.0 and metrics["lin_err"] >= 0.0
                assert metrics["survive"] == np.mean(metrics["survived"]) and len(metrics["survived"]) == 2
            for case in RISK_CASES:
                assert "beta" in evaluation["cases"][case]
                with np.load(trace_path(folder, 256, case)) as trace:
                    assert trace["atoms"].shape == (20, 8 if method == "huri" else 1)
                    assert trace["beta"].shape == trace["iqr"].shape == trace["force"].shape == (20,)
            curve = read_curve(folder)
            assert [row["timesteps"] for row in curve] == [64, 128, 192, 256]
    # The baseline's scalar critic reads no risk; HuRi's does.
    assert status_of(out, "huri", 0).evaluated["trained_to"] == 256
    baseline = json.loads(record_path(run_folder(out, ENV, "huri-baseline", 0), 256).read_text())
    assert all(baseline["cases"][case]["beta"] == 0.0 for case in RISK_CASES)


def test_the_same_command_skips_finished_runs(local_grid, conf: Path) -> None:
    out, _, _ = local_grid
    model_file = run_folder(out, ENV, "huri", 0) / f"{ENV}.zip"
    before = model_file.stat().st_mtime_ns
    lines: list[str] = []
    outcomes = run_experiment(
        out,
        ENV,
        ["huri", "huri-baseline"],
        [0, 1],
        256,
        TINY_EVAL,
        conf=conf,
        checkpoint_freq=128,
        echo=lines.append,
    )
    assert all(o.state == "done" and o.message == "finished earlier" for o in outcomes)
    assert "4 finished earlier, 0 to train or evaluate" in lines[0]
    assert model_file.stat().st_mtime_ns == before


def test_report_sets_the_grid_beside_the_papers_numbers(local_grid) -> None:
    out, _, _ = local_grid
    path = write_report(out)
    text = path.read_text()
    assert path == out / "report.md"
    for heading in (
        "Table 1 analog",
        "Fig. 3 analog",
        "Fig. 4 / Table 2 analog",
        "Tables 8 and 9 analog",
        "Fig. 5 analog",
        "orderings",
    ):
        assert heading in text
    assert "(0.856)" in text and "(0.575)" in text and "90.86" in text  # the paper's numbers
    assert "(0.578)" in text and "(0.927)" in text  # its terrain tables (8 and 9)
    assert "HuRi (`huri`)" in text and "Baseline (PPO) (`huri-baseline`)" in text
    assert "± " in text  # two seeds: confidence intervals
    assert (
        "Survival, sudden-centroid (Table 1): " in text and "IQR uneven > sudden push > plane, huri" in text
    )
    for figure in ("returns.png", "risk.png"):
        assert (out / figure).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert main(["report", str(out)]) == 0


# ----------------------------------------------------------------------------------------- interruption
def _wait_for_checkpoint(out: Path, method: str, seed: int, at_least: int, process: subprocess.Popen) -> int:
    """Poll the run folder until it has a checkpoint of ``at_least`` steps (the run still training)."""
    folder = run_folder(out, ENV, method, seed)
    for _ in range(6000):
        assert process.poll() is None, process.communicate()
        steps = RunState.read(folder).timesteps
        if steps >= at_least:
            assert steps < 8192, "the run finished before it could be interrupted"
            return steps
        time.sleep(0.05)
    raise AssertionError("no checkpoint appeared")


def test_a_killed_or_interrupted_command_continues_from_the_last_checkpoint(
    conf: Path, tmp_path: Path
) -> None:
    out = tmp_path / "exp"
    command = cli(
        "run", "--methods", "huri-no-rnd", "--seeds", "5", "--timesteps", "8192", "--eval-episodes", "2",
        "--eval-episode-steps", "20", "--checkpoint-freq", "512", "-conf", str(conf), "--out", str(out),
    )  # fmt: skip
    # 1. SIGKILL of the command alone: its pool process must die with it (no orphan writing the run).
    first = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    killed_at = _wait_for_checkpoint(out, "huri-no-rnd", 5, 1024, first)
    first.kill()
    first.communicate()
    # 2. Ctrl-C (SIGINT to the command): the run stops, exit status 130. A shell starts background jobs
    # with SIGINT ignored, and children inherit that: the command gets Python's default handling back.
    second = subprocess.Popen(
        command,
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),
    )
    interrupted_at = _wait_for_checkpoint(out, "huri-no-rnd", 5, killed_at + 1024, second)
    second.send_signal(signal.SIGINT)
    output, _ = second.communicate(timeout=120)
    assert second.returncode == 130, output
    assert "interrupted" in output
    # 3. The same command finishes the run.
    third = subprocess.run(command, capture_output=True, text=True, timeout=600, check=False)
    assert third.returncode == 0, third.stdout + third.stderr
    assert "all 1 runs done" in third.stdout
    status = status_of(out, "huri-no-rnd", 5)
    assert status.resumed_from[0] == killed_at and status.resumed_from[-1] >= interrupted_at
    assert killed_at < status.resumed_from[-1] < 8192
    assert status.trained_to == 8192 and status.steps == 8192 and status.state == "done"
    model, _ = load_run(run_folder(out, ENV, "huri-no-rnd", 5), ENV)
    assert model.num_timesteps == 8192
    steps = [row["timesteps"] for row in read_curve(run_folder(out, ENV, "huri-no-rnd", 5))]
    assert steps == list(range(64, 8192 + 1, 64))  # each rollout once: the rows after a checkpoint are redone
    state = RunState.read(run_folder(out, ENV, "huri-no-rnd", 5))  # the trainer's own record of the sessions
    assert [s["from_timesteps"] for s in state.sessions] == [0, *status.resumed_from]
    # 4. Finished: the command skips it.
    again = subprocess.run(command, capture_output=True, text=True, timeout=600, check=False)
    assert again.returncode == 0 and "1 finished earlier, 0 to train or evaluate" in again.stdout


# ------------------------------------------------------------------------------------------------- ray
def test_ray_backend_runs_the_grid_as_ray_tasks(conf: Path, tmp_path: Path) -> None:
    import ray

    ray.init(num_cpus=2, include_dashboard=False)
    try:
        outcomes = run_experiment(
            tmp_path / "exp",
            ENV,
            ["huri", "huri-cvar0.5"],
            [2],
            128,
            TINY_EVAL,
            backend="ray",
            conf=conf,
            checkpoint_freq=64,
            poll_seconds=0.5,
            echo=lambda line: None,
        )
    finally:
        ray.shutdown()
    assert sorted((o.method, o.state) for o in outcomes) == [("huri", "done"), ("huri-cvar0.5", "done")]
    for method in ("huri", "huri-cvar0.5"):
        status = status_of(tmp_path / "exp", method, 2)
        assert status.trained_to == 128 and status.eval_done == len(PROTOCOL)
    assert (write_report(tmp_path / "exp")).is_file()
    # The folder is the same for both backends: the local pool trains the runs on to a larger budget.
    outcomes = run_experiment(
        tmp_path / "exp", ENV, ["huri"], [2], 192, TINY_EVAL, conf=conf, checkpoint_freq=64, echo=print
    )
    status = status_of(tmp_path / "exp", "huri", 2)
    assert outcomes[0].state == "done" and status.resumed_from == [128] and status.steps == 192
    assert status.evaluated["trained_to"] == 192


# ----------------------------------------------------------------------------------- errors and folders
def test_unknown_methods_envs_and_backends_are_refused(tmp_path: Path, capsys) -> None:
    base = ["run", "--timesteps", "64", "--seeds", "0", "--out", str(tmp_path / "exp")]
    assert main([*base, "--methods", "huri", "hury"]) == 2
    assert (
        "unknown method(s) hury; methods: huri-baseline, huri-neutral, huri-cvar0.5"
        in capsys.readouterr().err
    )
    assert main([*base, "--methods", "huri", "--env", "NoSuchEnv-v0"]) == 2
    assert "unknown env 'NoSuchEnv-v0'" in capsys.readouterr().err
    assert main([*base, "--methods", "huri", "--env", "Go2Like-v0"]) == 2
    assert "Go2Like-v0 is not evaluated by the grid" in capsys.readouterr().err
    assert main([*base, "--methods", "huri", "-conf", str(tmp_path / "none.yml")]) == 2
    assert "none.yml" in capsys.readouterr().err
    with pytest.raises(ExperimentError, match="unknown backend 'slurm'"):
        run_experiment(tmp_path / "exp", ENV, ["huri"], [0], 64, backend="slurm")
    with pytest.raises(ExperimentError, match="timesteps must be positive"):
        run_experiment(tmp_path / "exp", ENV, ["huri"], [0], 0)
    assert not (tmp_path / "exp").exists()  # nothing written for a refused command


def test_foreign_and_corrupt_folders_are_refused(tmp_path: Path, capsys, conf: Path) -> None:
    foreign = tmp_path / "foreign"
    foreign.mkdir()
    (foreign / "notes.txt").write_text("someone else's")
    base = ["run", "--methods", "huri", "--seeds", "0", "--timesteps", "64", "-conf", str(conf), "--out"]
    assert main([*base, str(foreign)]) == 2
    assert "is not empty and holds no experiment" in capsys.readouterr().err
    assert main(["report", str(foreign)]) == 2
    assert "holds no experiment" in capsys.readouterr().err

    corrupt = tmp_path / "corrupt"
    corrupt.mkdir()
    (corrupt / "experiment.json").write_text('{"format": "sb3-huri-experiment", "vers')
    assert main([*base, str(corrupt)]) == 2
    assert "experiment.json is corrupt" in capsys.readouterr().err
    (corrupt / "experiment.json").write_text('{"format": "another-tool"}')
    assert main(["report", str(corrupt)]) == 2
    assert "is not an sb3-huri experiment file" in capsys.readouterr().err

    # A run whose status was damaged: the report names the file and what to do.
    settings = Settings(ENV, {"n_envs": 2}, 64, runs=[("huri", 0)])
    out = tmp_path / "damaged"
    open_experiment(out, settings)
    folder = run_folder(out, ENV, "huri", 0)
    folder.mkdir(parents=True)
    (folder / "status.json").write_text("{")
    assert main(["report", str(out)]) == 2
    assert f"{folder / 'status.json'} is corrupt" in capsys.readouterr().err
    write_json(
        folder / "status.json",
        {"format": "sb3-huri-run", "version": 1, "method": "huri-cvar", "seed": 0, "env": ENV},
    )
    with pytest.raises(ExperimentError, match="belongs to huri-cvar seed 0"):
        write_report(out)


def test_a_continued_experiment_keeps_its_env_and_preset(tmp_path: Path) -> None:
    out = tmp_path / "exp"
    first = Settings(ENV, {"n_envs": 2, "n_steps": 32}, 1000, runs=[("huri", 0)])
    open_experiment(out, first)
    with pytest.raises(ExperimentError, match=r"another preset of Zerith1-v0 \(differs in: n_steps\)"):
        open_experiment(out, Settings(ENV, {"n_envs": 2, "n_steps": 64}, 1000, runs=[("huri", 0)]))
    with pytest.raises(ExperimentError, match="trains every run to 1000 steps; --timesteps 500"):
        open_experiment(out, Settings(ENV, first.preset, 500, runs=[("huri", 0)]))
    grown = open_experiment(
        out, Settings(ENV, first.preset, 2000, TINY_EVAL, runs=[("huri", 1), ("huri", 0)])
    )
    assert grown.runs == [("huri", 0), ("huri", 1)] and grown.timesteps == 2000 and grown.eval == TINY_EVAL
    assert json.loads((out / "experiment.json").read_text())["timesteps"] == 2000


def test_atomic_writes_leave_the_previous_file_when_a_write_fails(tmp_path: Path) -> None:
    path = tmp_path / "status.json"
    write_json(path, {"steps": 1})
    with pytest.raises(TypeError):
        write_json(path, {"steps": object()})
    assert json.loads(path.read_text()) == {"steps": 1}
    assert [p.name for p in tmp_path.iterdir()] == ["status.json"]


# ----------------------------------------------------------------------------------- statistics, ordering
def test_confidence_intervals_use_students_t() -> None:
    mean, half, n = mean_ci([1.0, 2.0, 3.0, math.nan])  # NaN is left out
    assert (mean, n) == (2.0, 3) and half == pytest.approx(4.303 / math.sqrt(3), rel=1e-4)  # t(2) = 4.303
    values = [0.2, 0.5, 0.9, 0.4, 0.7, 0.6, 0.3, 0.8, 0.1, 0.55, 0.65]  # t(10) = 2.228, from a printed table
    assert mean_ci(values)[1] == pytest.approx(2.228 * np.std(values, ddof=1) / math.sqrt(11), rel=1e-3)
    assert mean_ci([0.5])[:1] == (0.5,) and math.isnan(mean_ci([0.5])[1])
    assert mean_ci([])[2] == 0


def test_survival_intervals_are_wilsons() -> None:
    """SciPy's Wilson interval, pinned to the score interval's closed form the tables used before (at
    z = 1.96: the same to 1e-5) and to a few printed values."""
    for survived, episodes in ((0, 20), (1, 20), (13, 20), (20, 20), (37, 50), (61, 100), (297, 300)):
        share, z, n = survived / episodes, 1.96, episodes
        centre = (share + z * z / (2 * n)) / (1 + z * z / n)
        half = z * math.sqrt(share * (1 - share) / n + z * z / (4 * n * n)) / (1 + z * z / n)
        low, high = wilson_interval(share, episodes)
        assert (low, high) == pytest.approx((max(centre - half, 0.0), min(centre + half, 1.0)), abs=1e-5)
    assert wilson_interval(37 / 50, 50) == pytest.approx((0.6045, 0.8413), abs=5e-5)
    assert wilson_interval(0.0, 20) == pytest.approx((0.0, 0.1611), abs=5e-5)
    assert wilson_interval(0.0, 20)[1] > 0.1 and wilson_interval(1.0, 20)[0] < 0.9  # never empty at 0 or 1
    with pytest.raises(ValueError, match="at least one episode"):
        wilson_interval(0.5, 0)
    with pytest.raises(ValueError, match=r"in \[0, 1\]"):
        wilson_interval(1.5, 20)


def _paired(both: int, only_first: int, only_second: int, neither: int) -> tuple[np.ndarray, np.ndarray]:
    counts = (both, only_first, only_second, neither)
    first = np.repeat([True, True, False, False], counts)
    second = np.repeat([True, False, True, False], counts)
    return first, second


def test_paired_difference_interval_is_newcombes_and_covers() -> None:
    # Newcombe (1998), "Improved confidence intervals for the difference between binomial proportions based
    # on paired data", Statistics in Medicine 17:2635; its example of 36 / 12 / 2 / 0 of 50 pairs, method 10
    # (hybrid score, no continuity correction): 0.0569 to 0.3404 around 0.2.
    difference, low, high = paired_difference_interval(*_paired(36, 12, 2, 0))
    assert difference == pytest.approx(0.2)
    assert (low, high) == pytest.approx((0.0569, 0.3404), abs=1e-4)
    low, high = paired_difference_interval(*_paired(36, 2, 12, 0))[1:]  # the agents swapped: mirrored
    assert (low, high) == pytest.approx((-0.3404, -0.0569), abs=1e-4)
    never_disagree = paired_difference_interval(*_paired(90, 0, 0, 10))
    assert never_disagree[0] == 0.0 and never_disagree[1] < -0.01 and never_disagree[2] > 0.01
    assert paired_difference_interval(*_paired(100, 0, 0, 0))[1:] == pytest.approx((-0.037, 0.037), abs=2e-3)
    # Coverage of the true difference over simulated pairs of 100 robots: near the nominal 95%.
    rng = np.random.default_rng(0)
    for cells in ((0.6, 0.1, 0.05, 0.25), (0.3, 0.2, 0.2, 0.3)):
        truth = cells[1] - cells[2]
        hits = 0
        for _ in range(600):
            drawn = rng.choice(4, size=100, p=cells)
            _, low, high = paired_difference_interval(drawn <= 1, (drawn == 0) | (drawn == 2))
            hits += low <= truth <= high
        assert 0.92 <= hits / 600 <= 0.98, (cells, hits / 600)
    with pytest.raises(ValueError, match="two outcomes per robot"):
        paired_difference_interval(np.ones(3, dtype=bool), np.ones(4, dtype=bool))


def test_ordering_reports_holds_overlaps_and_breaks() -> None:
    order = ("huri", "huri-no-rnd", "huri-baseline")
    separated = {"huri": (0.9, 0.01, 3), "huri-no-rnd": (0.8, 0.01, 3), "huri-baseline": (0.6, 0.01, 3)}
    assert _ordering(order, separated).startswith("**holds**")
    overlapping = {**separated, "huri-no-rnd": (0.8, 0.2, 3)}
    assert "within the 95% CIs for huri/huri-no-rnd, huri-no-rnd/huri-baseline" in _ordering(
        order, overlapping
    )
    broken = {**separated, "huri-baseline": (0.85, 0.01, 3)}
    assert "**does not hold**" in _ordering(order, broken) and "huri-no-rnd 0.8 vs huri-baseline 0.85" in (
        _ordering(order, broken)
    )
    assert _ordering(order, {"huri": (0.9, 0.0, 1)}).startswith("not testable")
    assert "(huri < huri-baseline)" in _ordering(("huri", "huri-baseline"), {
        "huri": (0.1, math.nan, 1), "huri-baseline": (0.2, math.nan, 1)}, larger_first=False)  # fmt: skip


def test_next_run_folder_numbers_runs_as_rl_zoo_does(tmp_path: Path) -> None:
    for name in ("Zerith1-v0_1", "Zerith1-v0_3", "Zerith1-v0_notes"):
        (tmp_path / "huri" / name).mkdir(parents=True)
    assert next_run_folder(tmp_path, "huri") == tmp_path / "huri" / "Zerith1-v0_4"
    assert next_run_folder(tmp_path, "huri-cvar") == tmp_path / "huri-cvar" / "Zerith1-v0_1"


def test_experiments_cli_help_runs_without_training(tmp_path: Path) -> None:
    result = subprocess.run(cli("run", "--help"), capture_output=True, text=True, check=True, env=os.environ)
    assert "--backend {local,ray}" in result.stdout and "--workers" in result.stdout
