"""The training campaign: the queue's unfinished entries trained in the background, one stretch after another.

    python -m study campaign                       # train the queue (runs/campaign.yml)
    python -m study campaign --max-wall-minutes 150
    python -m study campaign --status              # where every entry stands

One campaign process at a time (a lock beside the queue file) runs up to ``--slots`` entries at once, each
in a child process pinned to a core of its own (two trainings of one core each train more samples per
second on 2 cores than one training of both: ``benchmarks/bench_core_split.py``). It takes the entries in
the queue's order, skipping those done, and never starts an entry while an earlier entry of the same run
folder is unfinished (the folder trains to 157M and is evaluated there before it trains on). An entry
trains with ``sb3_huri.runner.training.train_run`` up to its steps, with a robustness row every
``robustness_every`` steps, then is evaluated once (``final_evaluation.evaluate_entry``) and measured on
the queue's analyses (``campaign.analyses``: risk levels, survival over force magnitude). Each child logs
to ``<run>/train.log``.

SIGTERM or Ctrl-C to the campaign stops every child after the rollout under way, with a checkpoint; so
does ``--max-wall-minutes`` (analyses start no case after it; an evaluation or analysis under a signal
stops at once, keeping the cases it wrote). The same command continues every entry where it stopped.

A child dies with the campaign however the campaign dies (``campaign.child``: a campaign killed alone, by
``kill -9`` or the OOM killer, makes its children checkpoint and stop), and holds its run folder's lock
(``sb3_huri.runner.lock``) while it runs: a campaign started again waits for a folder still held (saying
by whom) instead of training it beside another writer. A child that fails says why in one line
(``<entry>: <file>: [Errno 28] No space left on device``), here and in ``--status``; one whose error a
second start would meet again (a full disk, a read-only one, a file of its run that does not read) is
left alone at once, its last good checkpoint kept; the other entries go on.
"""

from __future__ import annotations

import contextlib
import fcntl
import os
import signal
import subprocess
import sys
import time
from collections.abc import Callable, Iterator, Mapping
from pathlib import Path
from typing import Any

from sb3_huri.experiments.errors import ExperimentError
from sb3_huri.runner.files import RunError
from sb3_huri.runner.lock import holder
from study.campaign import progress
from study.campaign.child import EXIT_BUSY, EXIT_LEFT, read_failure
from study.campaign.queue import CampaignEntry, load_queue

LOG_FILE = "train.log"
TRIES = 2
"""Starts of an entry that ends unfinished (a crash, an error) before this campaign leaves it alone: a
second start resumes it from its newest checkpoint, which gets past a one-off failure; a third is not
made for one that fails every time (nor a second for an error a retry would meet again:
``campaign.child.EXIT_LEFT``)."""
POLL_S = 5.0
"""Seconds between the campaign's checks of its children."""


def runnable(entries: list[CampaignEntry], busy: set[Path], failed: set[str]) -> list[CampaignEntry]:
    """The entries that may start now, in queue order: unfinished, not failed in this campaign, their run
    folder not in `busy`, and no earlier entry of the same folder unfinished. An entry whose analyses failed
    (trained and evaluated: state ``measure``) does not hold its folder's later entries back."""
    waiting: set[Path] = set(busy)
    ready = []
    for entry in entries:
        if entry.name in failed:
            if progress.state(entry) != "measure":
                waiting.add(entry.run)
            continue
        if progress.state(entry) == "done":
            continue
        if entry.run not in waiting:
            ready.append(entry)
        waiting.add(entry.run)
    return ready


@contextlib.contextmanager
def campaign_lock(queue: Path) -> Iterator[None]:
    """Hold the queue's lock file while the campaign runs; ExperimentError if another campaign holds it."""
    path = queue.with_name(f".{queue.name}.lock")
    with path.open("a+") as handle:
        try:
            fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            raise ExperimentError(
                f"another campaign is running on {queue} (it holds {path}); one campaign process at a time"
            ) from None
        handle.seek(0)
        handle.truncate()
        handle.write(f"{os.getpid()}\n")
        handle.flush()
        yield


def _study_importable(environ: Mapping[str, str]) -> dict[str, str]:
    """`environ` with the folder holding ``study`` first on PYTHONPATH, so that a child started from
    another working folder imports the same study."""
    root = str(Path(__file__).resolve().parents[2])
    paths = [root, *(p for p in environ.get("PYTHONPATH", "").split(os.pathsep) if p and p != root)]
    return {**environ, "PYTHONPATH": os.pathsep.join(paths)}


def _child(entry: CampaignEntry, queue: Path, core: int | None, deadline: float | None) -> subprocess.Popen:
    """Start `entry` in a child process (pinned to `core`, unless None) that ends with this process,
    logging to its run folder."""
    command = [sys.executable, "-m", "study", "campaign", "--queue", str(queue)]
    command += ["--entry", entry.name, "--parent", str(os.getpid())]
    if deadline is not None:
        command += ["--max-wall-minutes", f"{max(deadline - time.time(), 0.0) / 60:.2f}"]
    entry.run.mkdir(parents=True, exist_ok=True)
    log = (entry.run / LOG_FILE).open("a")
    log.write(f"\n== {time.strftime('%Y-%m-%d %H:%M:%S')} campaign entry {entry.name}, core {core}\n")
    log.flush()
    pin = None if core is None else (lambda: os.sched_setaffinity(0, {core}))
    child = subprocess.Popen(
        command, stdout=log, stderr=subprocess.STDOUT, preexec_fn=pin, env=_study_importable(os.environ)
    )
    log.close()
    return child


Running = dict[int, tuple[CampaignEntry, subprocess.Popen]]
"""The entries training now and their child processes, by core slot."""


def run_campaign(
    queue: Path, slots: int | None = None, max_wall_s: float | None = None, echo=print
) -> list[CampaignEntry]:
    """Train the queue's entries, `slots` at once (default: one per core), until every entry is done, the
    wall time is reached or a stop signal comes; returns the entries still unfinished. An entry whose run
    folder another process holds waits until it is free (the campaign waits with it)."""
    cores = sorted(os.sched_getaffinity(0))
    slots = slots or len(cores)
    deadline = None if max_wall_s is None else time.time() + max_wall_s
    running: Running = {}
    failures: dict[str, int] = {}
    held: dict[Path, int] = {}  # run folders that entries ready to start wait for, and their holders
    stopping = False

    def stop(*_: object) -> None:
        nonlocal stopping
        stopping = True
        for _, child in running.values():
            child.send_signal(signal.SIGTERM)

    previous = {s: signal.signal(s, stop) for s in (signal.SIGTERM, signal.SIGINT)}
    entries = load_queue(queue)  # a bad queue file stops the campaign before it starts anything
    said = None
    try:
        with campaign_lock(queue):
            while True:
                entries, problem = _reread(queue, entries)
                if problem is not None and problem != said:
                    echo(f"{time.strftime('%H:%M:%S')} {problem}")
                said = problem
                out_of_time = deadline is not None and time.time() >= deadline
                if stopping or out_of_time:
                    held = {}
                else:
                    failed = {name for name, count in failures.items() if count >= TRIES}
                    held = _start(entries, running, failed, held, (queue, slots, cores, deadline), echo)
                if not running and not held:
                    break
                time.sleep(POLL_S)
                for slot, (entry, child) in list(running.items()):
                    if child.poll() is None:
                        continue
                    del running[slot]
                    out_of_time = deadline is not None and time.time() >= deadline
                    _report_end(entry, child.returncode, stopping or out_of_time, failures, echo, child.pid)
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)
    return [entry for entry in _reread(queue, entries)[0] if progress.state(entry) != "done"]


def _start(
    entries: list[CampaignEntry], running: Running, failed: set[str], held: dict[Path, int],
    where: tuple[Path, int, list[int], float | None], echo: Callable[[str], Any],
) -> dict[Path, int]:  # fmt: skip
    """Start the entries that may start now (``runnable``) in the free slots of `running`, but those whose
    run folder another process holds (a trainer still stopping, or someone else's), saying once which
    process each waits for; returns those folders and their holders. `where`: the queue file, the slots,
    the cores and the deadline."""
    queue, slots, cores, deadline = where
    ready = runnable(entries, {entry.run for entry, _ in running.values()}, failed)
    holders = {entry.run: pid for entry in ready if (pid := holder(entry.run)) is not None}
    for entry in ready:
        if entry.run in holders and held.get(entry.run) != holders[entry.run]:
            echo(
                f"{time.strftime('%H:%M:%S')} {entry.name} waits: another process (pid {holders[entry.run]}) "
                f"holds its run folder {entry.run}"
            )
    free = [slot for slot in range(slots) if slot not in running]
    for slot, entry in zip(free, [e for e in ready if e.run not in holders], strict=False):
        core = cores[slot % len(cores)] if slots > 1 else None
        running[slot] = (entry, _child(entry, queue, core, deadline))
        echo(f"{time.strftime('%H:%M:%S')} started {entry.name} on slot {slot}")
    return holders


def _reread(queue: Path, entries: list[CampaignEntry]) -> tuple[list[CampaignEntry], str | None]:
    """The queue file's entries as it is now (an entry added while the campaign runs is taken up), or, while
    it does not read (an edit under way, an entry this code cannot take), the entries last read and why: the
    entries running are never left without their campaign."""
    try:
        return load_queue(queue), None
    except RunError as error:
        return entries, f"the queue file does not read now ({error}); going on with it as last read"


def _report_end(
    entry: CampaignEntry,
    returncode: int,
    stopped: bool,
    failures: dict[str, int],
    echo: Callable[[str], Any],
    pid: int | None = None,
) -> None:
    """Say how an entry's child (process `pid`) ended, and why in one line if it failed; one that ended
    unfinished though nothing stopped it counts as a failure (started again until it has failed `TRIES`
    times, and not again after an error a retry would meet again; its ``<run>/train.log`` has the rest).
    A child that found its run folder held by another process did not fail: the entry starts again once the
    folder is free."""
    state = progress.state(entry)
    echo(f"{time.strftime('%H:%M:%S')} {entry.name}: exit {returncode}, {state}")
    if returncode == EXIT_BUSY:
        echo(f"{entry.name}: another process holds its run folder {entry.run}; started once it is free")
        return
    note = read_failure(entry, pid) if returncode != 0 else None
    if note is not None:
        echo(f"{entry.name}: {note['error']}")
    if stopped:
        if state != "done":
            echo(
                f"{entry.name} stopped at the wall-time limit or a stop signal, to go on from its checkpoint"
            )
        return
    if returncode != 0 or state != "done":
        lasting = returncode == EXIT_LEFT
        failures[entry.name] = TRIES if lasting else failures.get(entry.name, 0) + 1
        again = "started again" if failures[entry.name] < TRIES else "left alone"
        if lasting:
            again += (
                ": a second start would fail the same way; its last good checkpoint is kept, and the next "
                "campaign resumes from it once the cause is gone"
            )
        echo(f"{entry.name} ended unfinished ({failures[entry.name]} of {TRIES}): {again}")


def recent_rate(run: Path, rows: int = 200) -> float | None:
    """The run's training speed over its last `rows` rollouts (env steps per second of training time, from
    ``curve.csv``), or None before it has two rows."""
    from sb3_huri.runner.curve import read_curve

    curve = read_curve(run)[-rows:]
    if len(curve) < 2 or curve[-1]["wall_s"] <= curve[0]["wall_s"]:
        return None
    return (curve[-1]["timesteps"] - curve[0]["timesteps"]) / (curve[-1]["wall_s"] - curve[0]["wall_s"])


def status_table(queue: Path) -> str:
    """Every entry's protocol, method, seed, steps against its target, training hours, recent speed, the
    training hours left at that speed, and state; then the whole queue's steps trained against its total
    (each run folder counted once, at its largest target); then, for the entries that have one, why their
    run does not read or why their last child failed."""
    header = f"{'entry':24} {'protocol':10} {'method':14} seed {'steps':>12} {'target':>12} {'hours':>6}"
    lines = [f"{header} {'steps/s':>7} {'left h':>6} state"]
    entries = load_queue(queue)
    trained: dict[Path, int] = {}  # steps each run folder holds
    notes = []
    for entry in entries:
        line, trained[entry.run], note = _status_row(entry)
        lines.append(line)
        notes += [note] if note else []
    targets: dict[Path, int] = {}
    for entry in entries:
        targets[entry.run] = max(targets.get(entry.run, 0), entry.steps)
    done = sum(min(trained[run], target) for run, target in targets.items())
    total = sum(targets.values())
    lines.append(
        f"queue: {done:,} of {total:,} steps trained ({100 * done / total:.0f}%) in {len(targets)} run "
        f"folders, {total - done:,} left"
    )
    return "\n".join(lines + notes)


def _status_row(entry: CampaignEntry) -> tuple[str, int, str | None]:
    """The entry's row of the status table, the steps its run holds (0 where its state does not read), and
    a note: why its run does not read, or why its last child failed (None when neither)."""
    from sb3_huri.runner.state import RunState

    state, problem = progress.state(entry), progress.problem(entry)
    try:
        run_state = RunState.read(entry.run, entry.env_id)
        rate = recent_rate(entry.run) if state == "train" else None
    except RunError:
        run_state, rate = RunState(), None
    steps, hours = run_state.timesteps, run_state.wall_s / 3600
    speed = f"{rate:7.0f} {max(entry.steps - steps, 0) / rate / 3600:6.1f}" if rate else f"{'-':>7} {'-':>6}"
    line = (
        f"{entry.name:24} {entry.protocol:10} {entry.method:14} {entry.seed:4} "
        f"{steps:12,} {entry.steps:12,} {hours:6.2f} {speed} {state}"
    )
    failure = read_failure(entry)
    if problem is not None:
        return line, steps, f"{entry.name}: {problem}"
    if failure is not None:
        return line, steps, f"{entry.name}: failed {failure.get('when', '')}: {failure['error']}"
    return line, steps, None
