"""Training across sessions: newest checkpoint, learning curve, random states and curriculum stage, resumed
by `examples/train_zerith.py --resume` (sb3_huri.runner)."""

from __future__ import annotations

import csv
import errno
import json
import math
import os
import re
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import torch as th
import yaml
from huri_helpers import HOLD_RUN, tiny_robust_preset
from stable_baselines3.common.callbacks import BaseCallback, CallbackList
from stable_baselines3.common.vec_env import VecNormalize

import zerith_gym
from sb3_huri import HuRiPPO
from sb3_huri.huri.methods import DEFAULT_METHOD
from sb3_huri.runner.build import resume_overrides
from sb3_huri.runner.checkpoint import RunCheckpoint
from sb3_huri.runner.curve import CURVE_COLUMNS, append_row, read_curve, trim_curve
from sb3_huri.runner.fallback import damage, model_steps, previous_folder, recover
from sb3_huri.runner.files import RunError
from sb3_huri.runner.lock import RunBusy, hold_run, holder
from sb3_huri.runner.state import RunState, restore_random_states, start_on_levels, terrain_levels
from sb3_huri.runner.training import RunRequest, TrainingOptions, train_run
from sb3_huri.zoo import read_preset
from zerith_gym.sb3.callbacks import RandomizationCurriculum
from zerith_gym.terrain.levels import LevelRule

ROOT = Path(__file__).resolve().parent.parent
TRAIN = [sys.executable, str(ROOT / "examples" / "train_zerith.py")]


def _train(*args: str) -> None:
    result = subprocess.run(
        [*TRAIN, "--workers", "0", *args], capture_output=True, text=True, timeout=600, env=os.environ.copy()
    )
    assert result.returncode == 0, result.stderr[-3000:]


def test_a_run_resumes_from_its_newest_checkpoint_with_its_curve_state_and_stage(tmp_path):
    preset = tiny_robust_preset(tmp_path)
    _train("-conf", str(preset), "-f", str(tmp_path), "-n", "256", "--checkpoint-freq", "128", "--seed", "3")
    run = tmp_path / DEFAULT_METHOD / "Zerith1-v0_1"
    first = RunState.read(run)
    assert first.timesteps == 256 and len(first.sessions) == 1 and first.sessions[0]["to_timesteps"] == 256
    assert first.curriculum_stage is not None and first.curriculum_stage >= 1
    saved = HuRiPPO.load(run / "Zerith1-v0.zip")
    assert saved.num_timesteps == 256 and saved.desired_kl == 0.007
    assert saved.method == DEFAULT_METHOD  # the run folder is named after the method it trains

    with (run / "curve.csv").open("a") as file:  # a row that a stopped session wrote after its checkpoint
        file.write("320" + ",0" * (len(CURVE_COLUMNS) - 1) + "\n")
    # the rest of the budget, the run's algo and seed; hyperparameters changed as `rl_zoo3 train -params`
    _train(
        "--resume",
        str(run),
        "--checkpoint-freq",
        "128",
        "--device",
        "cpu",
        "-params",
        "mirror_coef:2.0",
        "desired_kl:0.01",
    )
    resumed = HuRiPPO.load(run / "Zerith1-v0.zip")
    assert (resumed.mirror_coef, resumed.desired_kl, resumed.n_steps) == (2.0, 0.01, 16)
    assert yaml.safe_load((run / "Zerith1-v0" / "config.yml").read_text())["mirror_coef"] == 2.0
    second = RunState.read(run)
    assert second.timesteps == 384 and len(second.sessions) == 2
    assert second.sessions[1]["from_timesteps"] == 256 and second.wall_s >= first.wall_s
    assert second.curriculum_stage >= first.curriculum_stage
    assert yaml.safe_load((run / "Zerith1-v0" / "args.yml").read_text())["seed"] == 3

    with (run / "curve.csv").open() as file:
        rows = list(csv.DictReader(file))
    assert list(rows[0]) == list(CURVE_COLUMNS)
    assert [int(r["timesteps"]) for r in rows] == list(range(64, 385, 64))
    walls = [float(r["wall_s"]) for r in rows]
    assert walls == sorted(walls)  # the resumed session's times continue the first's
    assert sorted(p.name for p in (run / "checkpoints").glob("*.zip")) == [
        f"rl_model_{steps}_steps.zip" for steps in (128, 256, 384)
    ]


def test_the_curve_skips_a_torn_row_and_is_cut_back_whole(tmp_path):
    row = dict.fromkeys(CURVE_COLUMNS, float("nan"))
    for steps in (64, 128, 192):
        append_row(tmp_path, {**row, "timesteps": steps, "wall_s": steps / 10, "ep_return": 1.5})
    with (tmp_path / "curve.csv").open("a") as file:
        file.write("256,25.6,3")  # a kill while the row was written
    rows = read_curve(tmp_path)
    assert [r["timesteps"] for r in rows] == [64, 128, 192] and rows[1]["ep_return"] == 1.5
    assert np.isnan(rows[0]["approx_kl"])
    trim_curve(tmp_path, 128)
    assert [r["timesteps"] for r in read_curve(tmp_path)] == [64, 128]
    assert not list(tmp_path.glob(".*.tmp"))


def test_a_curve_of_fewer_columns_takes_todays_header_and_keeps_its_rows(tmp_path):
    """A run begun before `terrain_level` and the risk columns existed: its rows stay, NaN in the new columns,
    new rows carry them."""
    old_columns = CURVE_COLUMNS[: CURVE_COLUMNS.index("terrain_level")]
    lines = [",".join(old_columns), ",".join(["64", "6.4", "1000", "2.5", *["0.1"] * (len(old_columns) - 4)])]
    (tmp_path / "curve.csv").write_text("\n".join(lines) + "\n")
    append_row(tmp_path, {**dict.fromkeys(CURVE_COLUMNS, 0.5), "timesteps": 128, "terrain_level": 3.25})
    with (tmp_path / "curve.csv").open() as file:
        assert next(csv.reader(file)) == list(CURVE_COLUMNS)
    rows = read_curve(tmp_path)
    assert [r["timesteps"] for r in rows] == [64, 128] and rows[0]["ep_return"] == 2.5
    assert math.isnan(rows[0]["terrain_level"]) and rows[1]["terrain_level"] == 3.25
    assert math.isnan(rows[0]["iqr_below"]) and rows[1]["iqr_below"] == 0.5


def test_random_states_come_back_from_a_checkpoint(tmp_path):
    preset = tiny_robust_preset(tmp_path)
    _train("-conf", str(preset), "-f", str(tmp_path), "-n", "64", "--checkpoint-freq", "64")
    run = tmp_path / DEFAULT_METHOD / "Zerith1-v0_1"
    assert restore_random_states(run)
    expected = (th.rand(3), np.random.rand(3))  # noqa: NPY002 (the global state SB3 uses)
    restore_random_states(run)
    np.testing.assert_array_equal(th.rand(3), expected[0])
    np.testing.assert_array_equal(np.random.rand(3), expected[1])  # noqa: NPY002
    assert not restore_random_states(tmp_path)
    state = json.loads((run / "Zerith1-v0" / "state.json").read_text())
    assert state["sessions"][0]["hardware"]


@pytest.mark.filterwarnings("ignore::sb3_huri.UnnormalizedRewardWarning")
def test_a_resumed_curriculum_goes_on_from_its_stage():
    """The first rollout of a resumed run trains at the stage the run had reached, not at the schedule's."""
    env = zerith_gym.make_vec_env(2, seed=0, scenario="robust", workers=0)
    model = HuRiPPO("MlpPolicy", env, n_steps=8, n_epochs=1, policy_kwargs=dict(net_arch=[8]), seed=0)
    model.num_timesteps = 900  # the schedule would allow stage 3 of 4
    curriculum = RandomizationCurriculum(steps=1000, stages=4, max_fall_rate=0.2, start_stage=2)
    model.learn(16, callback=curriculum, reset_num_timesteps=False)
    assert curriculum.stage == 2 and env.get_attr("scenario")[0].name == "robustx0.5"
    with pytest.raises(ValueError, match=r"start_stage must be an integer in \[0, stages=4\]"):
        RandomizationCurriculum(steps=1000, stages=4, start_stage=5)
    env.close()


def test_terrain_levels_are_read_from_a_wrapped_env_and_placed_again():
    env = VecNormalize(zerith_gym.make_vec_env(6, seed=0, scenario="terrain", command=(0.8, 0, 0), workers=0))
    env.reset()
    env.set_level_rule(LevelRule())
    saved = [9, 4, 7, 0, 9, 5]
    start_on_levels(env, saved)
    env.reset()
    env.step(np.zeros((6, 12)))
    assert terrain_levels(env) == saved
    columns = [data.qpos[1] for data in env.unwrapped.robots.sim.datas]  # kind columns lie along y
    assert columns[0] < columns[1] < columns[2] and np.allclose(columns[:3], columns[3:], atol=0.5)
    with pytest.warns(UserWarning, match="5 terrain levels saved, but the env has 6 robots"):
        assert not start_on_levels(env, saved[:5])
    env.close()
    plane = zerith_gym.make_vec_env(2, seed=0, workers=0)
    assert terrain_levels(plane) is None  # one tile: nothing to restore
    plane.close()


@pytest.mark.filterwarnings("ignore::sb3_huri.UnnormalizedRewardWarning")
def test_a_resumed_terrain_run_starts_its_robots_on_their_saved_levels(tmp_path):
    """`--resume` of a run on tiles: the terrain curriculum goes on from each robot's level."""
    presets = yaml.safe_load((ROOT / "hyperparams" / "huri_terrain.yml").read_text())
    preset = presets["Zerith1-v0"]
    preset.update(n_envs=6, n_steps=8, n_epochs=1, policy_kwargs="dict(net_arch=[16], log_std_init=-2.0)")
    preset["n_timesteps"] = 48
    path = tmp_path / "terrain.yml"
    path.write_text(yaml.safe_dump({"Zerith1-v0": preset}))
    _train("-conf", str(path), "-f", str(tmp_path), "--checkpoint-freq", "48")
    run = tmp_path / DEFAULT_METHOD / "Zerith1-v0_1"
    first = RunState.read(run)
    assert first.terrain_levels == [0, 0, 0, 1, 1, 1]  # the start levels: 3 kinds, robots 3-5 a level up
    state_file = run / "Zerith1-v0" / "state.json"
    planted = [9, 8, 9, 8, 9, 8]  # as if the curriculum had taken every robot near the top
    state_file.write_text(json.dumps({**json.loads(state_file.read_text()), "terrain_levels": planted}))
    _train("--resume", str(run), "-n", "48", "--checkpoint-freq", "48")
    resumed = RunState.read(run)
    assert resumed.timesteps == 96 and len(resumed.terrain_levels) == 6
    moved = np.abs(np.subtract(resumed.terrain_levels, planted))
    assert moved.max() <= 1  # at most one episode ended in 8 steps; without the levels they would be 0-1
    levels = [row["terrain_level"] for row in read_curve(run)]  # the curve's mean level per rollout
    assert levels[0] == 0.5 and levels[-1] == pytest.approx(np.mean(resumed.terrain_levels))
    _train("--resume", str(run), "--checkpoint-freq", "48")  # the budget is spent: no step, the same levels
    assert RunState.read(run).terrain_levels == resumed.terrain_levels


def test_a_resumed_run_takes_new_hyperparameters_but_keeps_its_networks(tmp_path):
    saved = read_preset("Zerith1-v0", ROOT / "hyperparams" / "huri_robust.yml")
    assert resume_overrides(saved, saved) == {}
    changed = {**saved, "mirror_coef": 4.0, "desired_kl": 0.01, "n_envs": 8}
    assert resume_overrides(saved, changed) == {"mirror_coef": 4.0, "desired_kl": 0.01}
    wider = {**saved, "policy_kwargs": "dict(net_arch=[512, 256], activation_fn=nn.ELU, log_std_init=-2.0)"}
    with pytest.raises(ValueError, match="keeps its networks: policy_kwargs"):
        resume_overrides(saved, wider)
    model = HuRiPPO("MlpPolicy", "Pendulum-v1", n_steps=16, policy_kwargs={"net_arch": [8]})
    model.save(tmp_path / "model.zip")
    assert HuRiPPO.load(tmp_path / "model.zip", mirror_coef=1.5).mirror_coef == 1.5
    with pytest.raises(ValueError, match="mirror_coef must be >= 0, got -1"):
        HuRiPPO.load(tmp_path / "model.zip", mirror_coef=-1.0)
    result = subprocess.run([*TRAIN, "-params", "mirror_coef=4"], capture_output=True, text=True, timeout=120)
    assert result.returncode == 2 and "KEY:VALUE pairs" in result.stderr


def test_resuming_a_folder_without_a_model_is_a_clear_error(tmp_path):
    result = subprocess.run([*TRAIN, "--resume", str(tmp_path)], capture_output=True, text=True, timeout=120)
    assert result.returncode != 0 and "no Zerith1-v0.zip there" in result.stderr


class _StopAt(BaseCallback):
    """Requests the checkpoint's stop at the given env step, as a SIGTERM handler would."""

    def __init__(self, checkpoint: RunCheckpoint, steps: int) -> None:
        super().__init__()
        self.checkpoint, self.steps = checkpoint, steps

    def _on_step(self) -> bool:
        if self.num_timesteps == self.steps:
            self.checkpoint.request_stop()
        return True


@pytest.mark.filterwarnings("ignore::sb3_huri.UnnormalizedRewardWarning")
def test_a_stop_request_ends_training_after_the_rollout_under_way_with_a_checkpoint(tmp_path):
    """What `kill` (SIGTERM) does to a training: the rollout under way is collected and learnt from, then
    the run saves a checkpoint that holds exactly the steps its model learnt from."""
    env = zerith_gym.make_vec_env(2, seed=0, workers=0)
    model = HuRiPPO("MlpPolicy", env, n_steps=8, n_epochs=1, policy_kwargs=dict(net_arch=[8]), seed=0)
    checkpoint = RunCheckpoint(tmp_path / "run", {"n_envs": 2}, {"seed": 0}, checkpoint_freq=10_000)
    model.learn(1000, callback=CallbackList([_StopAt(checkpoint, 22), checkpoint]))
    assert model._n_updates == 2  # the second rollout (steps 17-32) was finished and learnt from
    assert model.num_timesteps == 34  # one step of the third rollout, then the stop
    assert RunState.read(tmp_path / "run").timesteps == 32 == checkpoint.saved_steps
    saved = HuRiPPO.load(tmp_path / "run" / "Zerith1-v0.zip")
    assert saved.num_timesteps == 32 and saved._n_updates == 2
    env.close()


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads the worker processes from /proc")
@pytest.mark.filterwarnings("ignore::sb3_huri.UnnormalizedRewardWarning")
def test_a_sigterm_to_the_whole_process_group_still_ends_with_a_checkpoint(tmp_path):
    """`timeout`, `kill -- -PGID` and batch schedulers signal every process of the job: the worker processes
    must leave the stop to the trainer, which saves at its next step and then closes them."""
    preset = tiny_robust_preset(tmp_path)
    output = tmp_path / "train.log"
    log = output.open("w")
    command = [*TRAIN, "-conf", str(preset), "-f", str(tmp_path), "-n", "10000000", "--workers", "1"]
    command += ["--checkpoint-freq", "128", "--seed", "3"]
    job = subprocess.Popen(command, stdout=log, stderr=subprocess.STDOUT, start_new_session=True)
    run = tmp_path / DEFAULT_METHOD / "Zerith1-v0_1"
    try:
        deadline = time.monotonic() + 300
        while not (run / "Zerith1-v0" / "state.json").is_file():
            assert job.poll() is None and time.monotonic() < deadline, output.read_text()[-3000:]
            time.sleep(0.5)
        workers = [int(pid) for pid in Path(f"/proc/{job.pid}/task/{job.pid}/children").read_text().split()]
        os.killpg(job.pid, signal.SIGTERM)
        assert job.wait(timeout=120) == 0, output.read_text()[-3000:]
    finally:
        if job.poll() is None:
            os.killpg(job.pid, signal.SIGKILL)
        log.close()
    state = RunState.read(run)
    assert state.timesteps >= 128 and state.sessions[-1]["to_timesteps"] == state.timesteps
    assert HuRiPPO.load(run / "Zerith1-v0.zip").num_timesteps == state.timesteps
    assert workers, "the trainer should have started a worker process"
    for pid in workers:  # closed by the trainer, not left behind
        assert not Path(f"/proc/{pid}").exists() or "zombie" in Path(f"/proc/{pid}/status").read_text()


def test_hardware_names_the_processor_once(monkeypatch):
    import platform

    from sb3_huri.runner import state

    monkeypatch.setattr(platform, "machine", lambda: "x86_64")
    monkeypatch.setattr(platform, "processor", lambda: "x86_64")  # as on many Linux machines
    monkeypatch.setattr(state.os, "cpu_count", lambda: 16)
    assert state.hardware().startswith("x86_64 16 cores, ")
    monkeypatch.setattr(platform, "processor", lambda: "")
    assert state.hardware().startswith("x86_64 16 cores, ")
    monkeypatch.setattr(platform, "machine", lambda: "arm64")
    monkeypatch.setattr(platform, "processor", lambda: "arm")
    assert state.hardware().startswith("arm64 arm 16 cores, ")


def test_a_second_trainer_of_a_held_run_folder_is_refused_naming_the_holder(tmp_path):
    """One writer per run folder: while another process holds it, `train_run` is refused before it writes
    anything; the lock goes with its holder, however it dies (here a SIGKILL)."""
    preset = read_preset("Zerith1-v0", tiny_robust_preset(tmp_path))
    run = tmp_path / "run"
    holding = subprocess.Popen(
        [sys.executable, "-c", HOLD_RUN, str(run)], stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True
    )
    try:
        assert holding.stdout.readline() == "held\n"
        assert holder(run) == holding.pid
        refused = re.escape(f"{run} is held by another process (pid {holding.pid}")
        with pytest.raises(RunBusy, match=refused):
            train_run(RunRequest(run, preset, "huri", 0, until=64), TrainingOptions(workers=0, verbose=0))
        assert [path.name for path in run.iterdir()] == [".lock"]  # nothing of a run written
    finally:
        holding.kill()
        holding.wait()
    assert holder(run) is None
    with hold_run(run), hold_run(run):  # free again; nested in one process
        assert holder(run) == os.getpid()
    assert holder(run) is None


def _alive(pid: int) -> bool:
    """Whether process `pid` runs (a zombie has ended)."""
    try:
        return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0] != "Z"
    except FileNotFoundError:
        return False


CHILD = "import sys, time\nfrom sb3_huri.runner.lock import die_with_parent\n"
CHILD += "die_with_parent(int(sys.argv[1]))\nprint('watching', flush=True)\ntime.sleep(300)\n"
PARENT = "import os, subprocess, sys\n"
PARENT += "child = subprocess.Popen([sys.executable, '-c', sys.argv[1], str(os.getpid())])\n"
PARENT += "print(child.pid, flush=True)\nchild.wait()\n"


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads the processes from /proc")
def test_a_process_told_to_die_with_its_parent_ends_when_the_parent_is_killed():
    """A parent killed while its child watches it (the OS's parent-death signal), and one killed before the
    child could watch it (the child finds it gone): either way the child ends."""
    parents = [
        subprocess.Popen([sys.executable, "-c", PARENT, CHILD], stdout=subprocess.PIPE, text=True)
        for _ in range(2)
    ]
    children = [int(parent.stdout.readline()) for parent in parents]
    parents[0].kill()  # before its child has even imported the module
    assert parents[1].stdout.readline() == "watching\n"
    parents[1].kill()
    for parent in parents:
        parent.wait()
    deadline = time.monotonic() + 60
    while any(_alive(pid) for pid in children) and time.monotonic() < deadline:
        time.sleep(0.2)
    assert not any(_alive(pid) for pid in children)


def _cut(path: Path) -> None:
    path.write_bytes(path.read_bytes()[: path.stat().st_size // 2])


DAMAGES = {
    "a torn model": lambda run: _cut(run / "Zerith1-v0.zip"),
    "a state that is no JSON": lambda run: (run / "Zerith1-v0" / "state.json").write_text("{garbage"),
    "a normalizer that does not unpickle": lambda run: (run / "Zerith1-v0" / "vecnormalize.pkl").write_bytes(
        b"\x80\x04garbage"
    ),
    "a kill between the model and the state": lambda run: shutil.copyfile(
        previous_folder(run) / "Zerith1-v0" / "state.json", run / "Zerith1-v0" / "state.json"
    ),
}


@pytest.mark.filterwarnings("ignore::sb3_huri.UnnormalizedRewardWarning")
def test_a_damaged_newest_checkpoint_is_set_aside_and_the_run_resumes_from_the_previous_one(tmp_path):
    """The checkpoint before the newest is kept in <run>/.previous/; a newest one that does not load
    or does not agree with itself is moved aside (not deleted), the previous one takes its place, and the
    lost steps are named. A run without a previous checkpoint (one from before it was kept) says so."""
    preset = read_preset("Zerith1-v0", tiny_robust_preset(tmp_path))
    trained = tmp_path / "trained"
    options = TrainingOptions(checkpoint_freq=64, workers=0, verbose=0)
    assert train_run(RunRequest(trained, preset, "huri", 0, until=192), options) == 192
    assert RunState.read(previous_folder(trained)).timesteps == 128
    for kind, spoil in DAMAGES.items():
        run = tmp_path / kind.replace(" ", "-")
        shutil.copytree(trained, run)
        spoil(run)
        said = []
        recover(run, echo=said.append)
        assert damage(run) is None, kind
        assert RunState.read(run).timesteps == 128 == model_steps(run / "Zerith1-v0.zip"), kind
        assert "steps 128 to 192 are lost" in said[0], (kind, said)
        (aside,) = (run / "checkpoints").glob("damaged-*")
        assert (aside / "Zerith1-v0.zip").is_file() and str(aside) in said[0]
    run = tmp_path / "a-torn-model"
    assert train_run(RunRequest(run, preset, "huri", 0, until=256), options) == 256
    assert HuRiPPO.load(run / "Zerith1-v0.zip").num_timesteps == 256 == RunState.read(run).timesteps
    assert [row["timesteps"] for row in read_curve(run)] == [64, 128, 192, 256]  # the lost rows redone once
    assert [s["from_timesteps"] for s in RunState.read(run).sessions] == [0, 128]

    shutil.rmtree(previous_folder(trained))  # as in a run folder from before it was kept
    state = RunState.read(trained)
    state.timesteps = 128
    state.write(trained)
    recover(trained)  # it loads, but disagrees: resumed as it is, as before (the trainer warns)
    assert damage(trained) == ("its model holds 192 steps and its state.json 128 (a save cut short)", False)
    _cut(trained / "Zerith1-v0.zip")
    with pytest.raises(RunError, match=r"does not load .* no good previous checkpoint"):
        recover(trained)
    assert (trained / "Zerith1-v0.zip").is_file()  # left where it was


def test_a_curve_that_does_not_read_is_a_clear_error_and_a_failed_append_leaves_it_whole(tmp_path):
    row = {**dict.fromkeys(CURVE_COLUMNS, float("nan")), "timesteps": 64, "wall_s": 6.4}
    append_row(tmp_path, row)
    before = (tmp_path / "curve.csv").read_bytes()
    write = os.write

    def full_disk(descriptor: int, data: bytes) -> int:
        write(descriptor, data[:7])  # part of the row, then no more room
        raise OSError(errno.ENOSPC, "No space left on device")

    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(os, "write", full_disk)
        with pytest.raises(OSError, match="No space left on device") as failed:
            append_row(tmp_path, {**row, "timesteps": 128})
    assert failed.value.filename == str(tmp_path / "curve.csv")
    assert (tmp_path / "curve.csv").read_bytes() == before
    (tmp_path / "curve.csv").write_bytes(b"timesteps\n\xff\xfe\x00\x81")
    with pytest.raises(RunError, match=r"curve\.csv is corrupt"):
        read_curve(tmp_path)
