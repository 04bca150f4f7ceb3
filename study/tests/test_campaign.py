"""The training campaign: its queue file, the order entries start in, robustness rows while training, and
the whole queue trained by `python -m study campaign`
(study.campaign.scheduler)."""

from __future__ import annotations

import contextlib
import csv
import errno
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
import yaml
from huri_helpers import HOLD_RUN, ROOT, state_dicts_equal, tiny_robust_preset

from sb3_huri import HuRiPPO
from sb3_huri.experiments.errors import ExperimentError
from sb3_huri.runner.curve import read_curve
from sb3_huri.runner.robustness import CASES, read_rows
from sb3_huri.runner.state import RunState
from sb3_huri.runner.training import RobustnessSchedule, RunRequest, TrainingOptions, train_run
from sb3_huri.zoo import read_preset
from study.campaign import progress
from study.campaign.final_evaluation import QUADRUPED_CASES
from study.campaign.progress import run_entry
from study.campaign.queue import load_queue
from study.campaign.scheduler import _reread, campaign_lock, runnable, status_table


def _queue(folder: Path, entries: list[dict], **defaults) -> Path:
    """A queue file of `entries`; without analyses after the final evaluation unless `defaults` names them
    (tests/test_campaign_analyses.py measures them)."""
    defaults.setdefault("analyses", [])
    path = folder / "campaign.yml"
    path.write_text(yaml.safe_dump({"defaults": defaults, "entries": entries}))
    return path


def _entry(name: str, run: str, steps: int, method: str = "huri", seed: int = 0) -> dict:
    return dict(name=name, protocol="robust", method=method, seed=seed, run=run, conf="tiny.yml", steps=steps)


def test_the_projects_queue_is_valid_and_names_its_entries_once():
    entries = load_queue(ROOT / "runs" / "campaign.yml")
    assert len({e.name for e in entries}) == len(entries) >= 6
    assert (
        entries[0].name == "robust-huri-s0-pair" and entries[0].run == ROOT / "runs" / "huri" / "Zerith1-v0_6"
    )
    assert {e.protocol for e in entries} >= {"robust", "paper"}
    assert all(e.conf.is_file() for e in entries)


@pytest.mark.parametrize(
    ("change", "message"),
    [
        ({"protocol": "lab"}, "protocol 'lab' is not one of robust, robust-256, paper, terrain"),
        ({"method": "sac"}, "unknown method 'sac'"),
        ({"conf": "missing.yml"}, "missing.yml not found"),
        ({"conf": "../x.yml"}, "campaign.yml: entry a: conf: preset file ../x.yml not found"),
        ({"steps": "many"}, "campaign.yml: entry a: steps: seed and steps must be numbers, got 'many'"),
        ({"method": "sac"}, "campaign.yml: entry a: method: unknown method 'sac'"),
        ({"steps": "many"}, "seed and steps must be numbers"),
        ({"budget": 3}, "unknown budget"),
        ({"hyperparams": [256]}, "hyperparams must map preset names to values"),
    ],
)
def test_a_bad_queue_entry_is_a_clear_error(tmp_path, change, message):
    tiny_robust_preset(tmp_path)
    queue = _queue(tmp_path, [{**_entry("a", "a/Zerith1-v0_1", 64), **change}])
    with pytest.raises(ExperimentError, match=message):
        load_queue(queue)


def test_a_queue_with_a_repeated_name_or_no_entries_is_refused(tmp_path):
    tiny_robust_preset(tmp_path)
    with pytest.raises(ExperimentError, match="repeated: a"):
        load_queue(_queue(tmp_path, [_entry("a", "x", 64), _entry("a", "y", 64)]))
    (tmp_path / "empty.yml").write_text("defaults: {}\n")
    with pytest.raises(ExperimentError, match="a list under `entries:`"):
        load_queue(tmp_path / "empty.yml")


def test_a_queue_file_that_stops_reading_while_the_campaign_runs_leaves_it_on_the_entries_last_read(tmp_path):
    """The campaign re-reads its queue between checks of its children: an edit that names a method this code
    does not know (or a torn write) keeps it going with the queue as it last read, saying why."""
    tiny_robust_preset(tmp_path)
    queue = _queue(tmp_path, [_entry("a", "a/Zerith1-v0_1", 64)])
    entries, problem = _reread(queue, [])
    assert [entry.name for entry in entries] == ["a"] and problem is None
    _queue(tmp_path, [_entry("a", "a/Zerith1-v0_1", 64), _entry("b", "b/Zerith1-v0_1", 64, "huri-next")])
    kept, problem = _reread(queue, entries)
    assert kept is entries
    assert "unknown method 'huri-next'" in problem and "going on with it as last read" in problem


def _fake_state(run: Path, steps: int) -> None:
    (run / "Zerith1-v0").mkdir(parents=True)
    (run / "Zerith1-v0" / "state.json").write_text(f'{{"timesteps": {steps}, "wall_s": 0, "sessions": []}}')


def test_entries_start_in_queue_order_one_per_run_folder_and_never_before_an_earlier_one_of_it(tmp_path):
    tiny_robust_preset(tmp_path)
    queue = _queue(
        tmp_path,
        [
            _entry("a-first", "a", 100),
            _entry("b", "b", 100),
            _entry("a-later", "a", 200),
            _entry("c", "c", 100),
            _entry("d-done", "d", 100),
        ],
    )
    _fake_state(tmp_path / "d", 100)
    (tmp_path / "d" / "evaluations").mkdir()
    (tmp_path / "d" / "evaluations" / "100.json").write_text('{"entry": "d-done"}')
    entries = load_queue(queue)
    assert [progress.state(e) for e in entries] == ["new", "new", "new", "new", "done"]
    names = [e.name for e in runnable(entries, busy=set(), failed=set())]
    assert names == ["a-first", "b", "c"]  # a-later waits for a-first, whatever the free slots
    assert [e.name for e in runnable(entries, busy={tmp_path / "b"}, failed=set())] == ["a-first", "c"]
    assert [e.name for e in runnable(entries, busy=set(), failed={"a-first"})] == ["b", "c"]
    table = status_table(queue).splitlines()
    assert "d-done" in table[-2] and table[-2].endswith("done")
    # a-later's 200 counts for folder a, a-first's 100 does not: 200 + 100 + 100 + 100, of which d's 100
    assert table[-1] == "queue: 100 of 500 steps trained (20%) in 4 run folders, 400 left"


def test_one_campaign_at_a_time(tmp_path):
    queue = tmp_path / "campaign.yml"
    queue.write_text("entries: []\n")
    with (
        campaign_lock(queue),
        pytest.raises(ExperimentError, match="another campaign is running"),
        campaign_lock(queue),
    ):
        pass


def test_training_passes_its_marks_with_a_kept_checkpoint_and_a_robustness_row_each(tmp_path):
    """Rows come from the policy at the mark's checkpoint; their evaluation time is not training time."""
    preset = read_preset("Zerith1-v0", tiny_robust_preset(tmp_path))
    run = tmp_path / "run"
    schedule = RobustnessSchedule(every=128, episodes=2, seed=1000, episode_steps=20)
    options = TrainingOptions(checkpoint_freq=10_000, robustness=schedule, workers=0, verbose=0)
    assert train_run(RunRequest(run, preset, "huri", 0, until=256), options) == 256
    rows = read_rows(run)
    assert list(rows) == [128, 256]
    assert all(0.0 <= float(rows[128][case]) <= 1.0 for case in CASES)
    assert rows[256]["episodes"] == "2" and float(rows[256]["wall_s"]) <= RunState.read(run).wall_s
    kept = sorted(p.name for p in (run / "checkpoints").iterdir())
    assert kept == [f"rl_model_{s}_steps.zip" for s in (128, 256)] + [
        f"rl_model_vecnormalize_{s}_steps.pkl" for s in (128, 256)
    ]
    # Evaluating between rollouts changes nothing the training learns: the same run without rows.
    plain = TrainingOptions(checkpoint_freq=10_000, workers=0, verbose=0)
    assert train_run(RunRequest(tmp_path / "plain", preset, "huri", 0, until=256), plain) == 256
    state_dicts_equal(
        HuRiPPO.load(run / "Zerith1-v0.zip").policy.state_dict(),
        HuRiPPO.load(tmp_path / "plain" / "Zerith1-v0.zip").policy.state_dict(),
    )
    with pytest.raises(ValueError, match="a run of huri, not huri-baseline"):
        train_run(RunRequest(run, preset, "huri-baseline", 0, until=320), options)


def test_the_campaign_trains_and_evaluates_its_queue_two_entries_at_once(tmp_path):
    """The real command on a tiny queue: both entries trained side by side to their steps, with their
    robustness rows and final evaluations; an entry that fails is started once more, then left alone while
    the others go on; run again, the command has nothing left to do but the failing entry."""
    tiny_robust_preset(tmp_path)
    broken = yaml.safe_load((tmp_path / "tiny.yml").read_text())
    broken["Zerith1-v0"]["n_epochs"] = 0  # refused by HuRiPPO when the entry starts
    (tmp_path / "broken.yml").write_text(yaml.safe_dump(broken))
    defaults = dict(robustness_every=128, robustness_episodes=2, eval_episodes=2, episode_steps=10)
    entries = [
        {**_entry("broken", "broken/Zerith1-v0_1", 128), "conf": "broken.yml"},
        _entry("huri-s0", "huri/Zerith1-v0_1", 128),
        {
            **_entry("ppo-s0", "ppo/Zerith1-v0_1", 128, "huri-baseline"),
            "hyperparams": {"n_envs": 8, "n_steps": 8},
        },
    ]
    queue = _queue(tmp_path, entries, **defaults)
    command = [
        sys.executable,
        "-m",
        "study",
        "campaign",
        "--queue",
        str(queue),
        "--slots",
        "2",
    ]
    result = subprocess.run(command, capture_output=True, text=True, timeout=600, env=os.environ.copy())
    logs = "".join(p.read_text() for p in tmp_path.glob("*/Zerith1-v0_1/train.log"))
    assert result.returncode == 1, result.stdout + result.stderr + logs[-3000:]
    assert "broken ended unfinished (1 of 2): started again" in result.stdout, result.stdout
    assert "broken ended unfinished (2 of 2): left alone" in result.stdout
    assert "1 entries unfinished" in result.stdout and "n_epochs" in logs
    for run in (tmp_path / "huri" / "Zerith1-v0_1", tmp_path / "ppo" / "Zerith1-v0_1"):
        assert RunState.read(run).timesteps == 128
        assert list(read_rows(run)) == [128]
        assert len(list((run / "evaluations").glob("128.json"))) == 1
        with (run / "curve.csv").open() as file:
            assert [int(r["timesteps"]) for r in csv.DictReader(file)] == [64, 128]
    assert [progress.state(e) for e in load_queue(queue)] == ["new", "done", "done"]
    config = dict(
        yaml.safe_load((tmp_path / "ppo" / "Zerith1-v0_1" / "Zerith1-v0" / "config.yml").read_text())
    )
    assert (config["n_envs"], config["n_steps"]) == (8, 8)  # the entry's hyperparams over its preset's 4 x 16
    again = subprocess.run(command, capture_output=True, text=True, timeout=120, env=os.environ.copy())
    assert (
        again.returncode == 1
        and "started huri-s0" not in again.stdout
        and "started ppo-s0" not in again.stdout
    )


def test_an_entry_stopped_at_the_wall_time_limit_is_not_counted_as_a_failure(tmp_path):
    """The child ends unfinished at the limit (exit 1); the campaign says it stopped, not that it failed."""
    tiny_robust_preset(tmp_path)
    queue = _queue(tmp_path, [_entry("long", "long/Zerith1-v0_1", 10**6)])
    command = [sys.executable, "-m", "study", "campaign", "--queue", str(queue)]
    result = subprocess.run(
        [*command, "--max-wall-minutes", "0.05"],
        capture_output=True,
        text=True,
        timeout=300,
        env=os.environ.copy(),
    )
    assert result.returncode == 1, result.stdout + result.stderr
    assert "long stopped at the wall-time limit" in result.stdout, result.stdout
    assert "ended unfinished" not in result.stdout and "started again" not in result.stdout


def test_the_device_chunk_script_trains_an_entry_and_packs_its_run_folder(tmp_path):
    """`study/device/campaign_chunk.sh` (what a lent machine runs): the entry trained and evaluated
    through the real command, its run folder packed without checkpoints/, and unpacked elsewhere a run that
    the queue reads as done."""
    import tarfile

    tiny_robust_preset(tmp_path)
    queue = _queue(tmp_path, [_entry("huri-s0", "huri/Zerith1-v0_1", 64)], eval_episodes=2, episode_steps=10)
    (tmp_path / "huri" / "Zerith1-v0_1" / "checkpoints").mkdir(parents=True)
    (tmp_path / "huri" / "Zerith1-v0_1" / "checkpoints" / "old.zip").write_bytes(b"stays here")
    out = tmp_path / "out"
    env = {**os.environ, "QUEUE": str(queue), "PYTHON": sys.executable, "OUT": str(out)}
    script = ROOT / "study" / "device" / "campaign_chunk.sh"
    result = subprocess.run(["bash", str(script), "huri-s0", "2"], capture_output=True, text=True,
                            timeout=300, env=env, cwd=tmp_path)  # fmt: skip
    assert result.returncode == 0, result.stdout + result.stderr + (out / "train.log").read_text()[-3000:]
    assert "packed into" in result.stdout and " done" in result.stdout
    with tarfile.open(out / "run.tar") as packed:
        names = packed.getnames()
        assert not [name for name in names if "checkpoints" in name]
        unpacked = tmp_path / "elsewhere"
        packed.extractall(unpacked, filter="data")
    (run,) = [unpacked / name for name in names if name.endswith("Zerith1-v0_1")]
    assert RunState.read(run).timesteps == 64 and (run / "evaluations" / "64.json").is_file()
    bad = subprocess.run(["bash", str(script), "nobody"], capture_output=True, text=True, timeout=120,
                         env=env, cwd=tmp_path)  # fmt: skip
    assert bad.returncode == 2 and "no entry named 'nobody'" in bad.stderr


def test_a_quadruped_entry_trains_go2like_and_is_evaluated_on_its_own_cases(tmp_path):
    """A `quadruped` entry: the run folder holds `Go2Like-v0` files, no Table-1 robustness rows (they are
    Zerith-1's), and a final evaluation on the quadruped's cases (plane walking, Table 8's platforms)."""
    presets = yaml.safe_load((ROOT / "hyperparams" / "huri.yml").read_text())
    preset = presets["Go2Like-v0"]
    preset.update(n_envs=4, n_steps=16, n_epochs=1, n_timesteps=128, policy_kwargs="dict(net_arch=[16])")
    (tmp_path / "go2.yml").write_text(yaml.safe_dump({"Go2Like-v0": preset}))
    entry = dict(name="go2-s0", protocol="quadruped", method="huri", seed=0, run="go2/Go2Like-v0_1",
                 conf="go2.yml", steps=64)  # fmt: skip
    queue = _queue(
        tmp_path, [entry], robustness_every=32, robustness_episodes=2, eval_episodes=2, episode_steps=10
    )
    (loaded,) = load_queue(queue)
    assert loaded.env_id == "Go2Like-v0" and progress.state(loaded) == "new"
    assert run_entry(loaded, workers=0) == "done"
    run = tmp_path / "go2" / "Go2Like-v0_1"
    assert RunState.read(run, "Go2Like-v0").timesteps == 64 and (run / "Go2Like-v0.zip").is_file()
    assert not list(read_rows(run))  # no Zerith-1 Table-1 rows for a quadruped
    record = json.loads((run / "evaluations" / "64.json").read_text())
    assert set(record["cases"]) == set(QUADRUPED_CASES)
    assert all(len(case["survived"]) == 2 for case in record["cases"].values())
    args = yaml.safe_load((run / "Go2Like-v0" / "args.yml").read_text())
    assert args["env"] == "Go2Like-v0" and args["env_kwargs"]["scenario"] == "quadruped-train"


def test_a_full_disk_stops_its_entry_at_once_saying_so_and_keeps_its_last_good_checkpoint(
    tmp_path, monkeypatch
):
    """A checkpoint whose write fails for want of space: its temporary file is removed, the checkpoint
    before it stays the newest (whole and agreeing with itself), the campaign prints the file and the error
    in one line, does not start the entry a second time, and `--status` says why; once there is room, the
    next campaign resumes from that checkpoint."""
    import torch as th

    from sb3_huri.runner.folder import load_run
    from study.campaign import child, scheduler

    tiny_robust_preset(tmp_path)
    queue = _queue(tmp_path, [_entry("f-huri", "f/Zerith1-v0_1", 192)], robustness_every=10**9,
                   eval_episodes=1, episode_steps=5)  # fmt: skip
    (entry,) = load_queue(queue)
    monkeypatch.setattr(progress, "CHECKPOINT_FREQ", 64)
    save, random_states = th.save, []

    def full_disk(obj: object, file: object, *args: object, **kwargs: object) -> None:
        if str(file).endswith(".tmp.pt"):  # rng.pt, written after the model and normalizer
            random_states.append(file)
            if len(random_states) == 2:  # the second checkpoint, at 128 steps
                Path(file).write_bytes(b"half a file")
                raise OSError(errno.ENOSPC, "No space left on device")
        return save(obj, file, *args, **kwargs)

    monkeypatch.setattr(th, "save", full_disk)
    assert child.run_child(entry) == child.EXIT_LEFT
    run = entry.run
    assert RunState.read(run).timesteps == 64 == HuRiPPO.load(run / "Zerith1-v0.zip").num_timesteps
    assert load_run(run, "Zerith1-v0")[1] is not None  # its normalizer loads too
    assert not [path for path in run.rglob("*") if ".tmp" in path.name]
    said, failures = [], {}
    scheduler._report_end(entry, child.EXIT_LEFT, False, failures, said.append, os.getpid())
    assert f"f-huri: {run / 'Zerith1-v0' / 'rng.pt'}: [Errno 28] No space left on device" in said, said
    assert said[-1].startswith("f-huri ended unfinished (2 of 2): left alone: a second start would fail")
    assert runnable([entry], set(), set(failures)) == []
    note = status_table(queue).splitlines()[-1]
    assert note.startswith("f-huri: failed ") and note.endswith("rng.pt: [Errno 28] No space left on device")
    monkeypatch.setattr(th, "save", save)  # room again
    assert child.run_child(entry) == 0 and progress.state(entry) == "done"
    assert [s["from_timesteps"] for s in RunState.read(run).sessions] == [0, 64]
    assert not (run / child.FAILURE_FILE).exists()


def test_an_entry_whose_run_does_not_read_is_left_alone_and_the_others_go_on(tmp_path):
    """Garbage in one entry's state.json: the queue reads, the entry is `damaged` (its trainer would fall
    back to a previous checkpoint; it has none), its child fails at once saying which file, and only that
    entry is left alone."""
    from study.campaign.child import EXIT_LEFT, run_child
    from study.campaign.scheduler import TRIES, _report_end

    tiny_robust_preset(tmp_path)
    queue = _queue(tmp_path, [_entry("bad", "bad", 64), _entry("good", "good", 64)])
    (tmp_path / "bad" / "Zerith1-v0").mkdir(parents=True)
    (tmp_path / "bad" / "Zerith1-v0" / "state.json").write_text("\x00 not a state")
    entries = load_queue(queue)
    assert [progress.state(entry) for entry in entries] == ["damaged", "new"]
    assert "state.json is corrupt" in progress.problem(entries[0])
    assert [entry.name for entry in runnable(entries, set(), set())] == ["bad", "good"]
    table = status_table(queue).splitlines()
    assert table[1].endswith(" damaged") and table[-1].startswith("bad: ") and "state.json" in table[-1]
    assert run_child(entries[0]) == EXIT_LEFT
    said, failures = [], {}
    _report_end(entries[0], EXIT_LEFT, False, failures, said.append, os.getpid())
    assert any(line.startswith("bad: ") and "state.json is corrupt" in line for line in said), said
    assert failures == {"bad": TRIES} and "left alone" in said[-1]
    assert [entry.name for entry in runnable(entries, set(), set(failures))] == ["good"]


def test_an_entry_whose_run_folder_another_process_holds_waits_until_it_is_free(tmp_path, monkeypatch):
    """A campaign started while a trainer of the last one still stops (or another trainer runs the folder):
    the entry is not started beside it, the campaign says once whom it waits for, and starts the entry when
    the folder is free; a child refused the folder did not fail."""
    from study.campaign import scheduler
    from study.campaign.child import EXIT_BUSY

    tiny_robust_preset(tmp_path)
    entries = load_queue(_queue(tmp_path, [_entry("a", "a/Zerith1-v0_1", 64)]))
    run = entries[0].run
    holding = subprocess.Popen(
        [sys.executable, "-c", HOLD_RUN, str(run)], stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True
    )
    monkeypatch.setattr(scheduler, "_child", lambda entry, *_: f"child of {entry.name}")
    running, said, where = {}, [], (tmp_path / "campaign.yml", 1, [0], None)
    try:
        assert holding.stdout.readline() == "held\n"
        held = scheduler._start(entries, running, set(), {}, where, said.append)
        assert held == {run: holding.pid} and not running
        assert said[0].endswith(f"a waits: another process (pid {holding.pid}) holds its run folder {run}")
        assert scheduler._start(entries, running, set(), held, where, said.append) == held and len(said) == 1
    finally:
        holding.kill()
        holding.wait()
    assert scheduler._start(entries, running, set(), held, where, said.append) == {}
    assert running == {0: (entries[0], "child of a")} and said[-1].endswith("started a on slot 0")
    failures, said = {}, []
    scheduler._report_end(entries[0], EXIT_BUSY, False, failures, said.append)
    assert not failures and "started once it is free" in said[-1]


def _children(pid: int) -> list[int]:
    return [int(child) for child in Path(f"/proc/{pid}/task/{pid}/children").read_text().split()]


def _alive(pid: int) -> bool:
    """Whether process `pid` runs (a zombie has ended)."""
    try:
        return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0] != "Z"
    except FileNotFoundError:
        return False


def _kill_the_campaign_alone(tmp_path: Path) -> tuple[list[str], Path]:
    """Start a campaign of one long entry, wait for its first checkpoint, `kill -9` the campaign's own
    process (as an out-of-memory kill would) and wait for its trainer to end; the campaign's command and
    the entry's run folder."""
    tiny_robust_preset(tmp_path)
    queue = _queue(tmp_path, [_entry("long", "long/Zerith1-v0_1", 10**6)], robustness_every=64,
                   robustness_episodes=1, episode_steps=5)  # fmt: skip
    run = tmp_path / "long" / "Zerith1-v0_1"
    command = [
        sys.executable,
        "-m",
        "study",
        "campaign",
        "--queue",
        str(queue),
        "--slots",
        "1",
    ]
    with (tmp_path / "first.log").open("w") as log:
        first = subprocess.Popen(command, stdout=log, stderr=subprocess.STDOUT, start_new_session=True)
    try:
        deadline = time.monotonic() + 300
        while RunState.read(run).timesteps < 64:
            assert first.poll() is None and time.monotonic() < deadline, (run / "train.log").read_text()[
                -3000:
            ]
            time.sleep(0.5)
        trainers = _children(first.pid)
        first.kill()
        first.wait()
        while any(_alive(pid) for pid in trainers) and time.monotonic() < deadline:
            time.sleep(0.2)
        assert trainers and not any(_alive(pid) for pid in trainers), "a trainer outlived its campaign"
    finally:
        with contextlib.suppress(ProcessLookupError):
            os.killpg(first.pid, signal.SIGKILL)
    return command, run


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads the processes from /proc")
def test_a_campaign_killed_alone_takes_its_trainers_with_it(tmp_path):
    """`kill -9` of the campaign's own process: its trainer (told by the OS) checkpoints and ends instead of
    training on beside the next campaign; it leaves its run folder free and a whole checkpoint."""
    from sb3_huri.runner.lock import holder

    _, run = _kill_the_campaign_alone(tmp_path)
    assert holder(run) is None
    state = RunState.read(run)
    assert state.timesteps >= 64 and HuRiPPO.load(run / "Zerith1-v0.zip").num_timesteps == state.timesteps
    assert "checkpoint:" in (run / "train.log").read_text().rsplit("== ", 1)[-1]


@pytest.mark.slow
@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads the processes from /proc")
def test_a_campaign_started_after_one_killed_alone_resumes_its_runs_as_their_one_writer(tmp_path):
    """The above, then the next campaign: it resumes the run from the checkpoint the trainer left, and the
    run's curve and state are those of one writer (steps increasing strictly, the state that of the newest
    model)."""
    command, run = _kill_the_campaign_alone(tmp_path)
    stopped_at = RunState.read(run).timesteps
    again = subprocess.run(
        [*command, "--max-wall-minutes", "0.05"], capture_output=True, text=True, timeout=300
    )
    assert "started long" in again.stdout, again.stdout + (run / "train.log").read_text()[-3000:]
    state = RunState.read(run)
    assert (
        state.timesteps > stopped_at and HuRiPPO.load(run / "Zerith1-v0.zip").num_timesteps == state.timesteps
    )
    steps = [row["timesteps"] for row in read_curve(run)]
    assert steps == sorted(set(steps)) and steps[-1] >= state.timesteps  # increasing strictly: one writer
    assert [s["from_timesteps"] for s in state.sessions] == [0, stopped_at]
