"""`WorkerPool`: n robots in contiguous slices, each stepped by its own `ZerithBatch`, in parallel processes.

The task logic (numpy over the batch) holds Python's GIL, so threads cannot share it out; processes can.
Slice k owns robots [start_k, stop_k) with their physics *and* task state, so everything a control step
costs runs in parallel. The calling process steps the first slice itself while `workers` worker processes
step the others (as a thread pool's caller takes a share of the work): on c cores, c - 1 workers keep
every core busy and the caller never sits idle waiting. The shape is that of EnvPool and SB3's
`SubprocVecEnv`, with the data in shared memory instead of pickled messages:

- one shared block holds the actions and every per-robot output (observations, rewards, episode ends,
  reward terms, info values) as numpy views, the same in every process; a slice reads and writes only
  its own rows;
- a step is one byte sent to each worker and one byte back; robots whose episode ended are reset inside
  their slice in the same step (their terminal observations are kept in the block), so a step costs
  one round trip whatever happens in it;
- episode statistics are summed by the caller from the shared rewards and reward terms.

Workers are forked where the OS can (Linux): they start in a fraction of a second, and scripts, notebooks
and RL Zoo work without an `if __name__ == "__main__":` guard. A worker runs only numpy and MuJoCo, never
torch, so the parent's threads do not matter to it. Elsewhere (macOS, Windows) they are spawned, which
needs that guard in the script that creates the env.

A robot gets exactly the calls it would get in a single `ZerithBatch`, with its own random generator, so
the transitions do not depend on the number of workers (tested). The pool has `ZerithBatch`'s interface
(`seed`, `reset`, `step`, `set_scenario`, `commands`, `close`), which is all `ZerithVecEnv` uses.
"""

from __future__ import annotations

import contextlib
import ctypes
import itertools
import multiprocessing as mp
import os
import pickle
import signal
import traceback
import weakref
from collections.abc import Mapping
from multiprocessing.connection import Connection
from typing import Any

import numpy as np

from zerith_gym.core.contract import BatchStep, check_scenario_change
from zerith_gym.core.scenarios import Scenario
from zerith_gym.core.task import LocomotionTask, StepOutput
from zerith_gym.cpu.batch import ZerithBatch
from zerith_gym.options import ZerithOptions
from zerith_gym.terrain.levels import LevelRule

MIN_ROBOTS_PER_WORKER = 8
"""Below this many robots per slice the hand-over costs more than the parallel work gains."""

_STEP, _OK = b"s", b"k"

_PARENT_CHECK_S = 1.0
"""How often (s) an idle worker checks that the process that made it is still alive."""


def available_cores() -> int:
    """CPU cores this process may run on."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        return os.cpu_count() or 1


def default_workers(num_robots: int, cores: int | None = None) -> int:
    """Worker processes for `num_robots` robots on `cores` cores (default: this machine's): one slice of
    robots per core (the caller steps one of them), at least `MIN_ROBOTS_PER_WORKER` robots per slice; 0
    (every robot in the calling process) where that gives a single slice."""
    cores = available_cores() if cores is None else cores
    return max(min(cores, num_robots // MIN_ROBOTS_PER_WORKER) - 1, 0)


Columns = dict[str, tuple[type, tuple[int, ...]]]


def step_columns(task: LocomotionTask) -> tuple[Columns, Columns]:
    """Dtype and per-robot shape of each field of `StepOutput` (the step record the shared block holds),
    and of the array fields of `BatchStep` other than `out`, for robots of `task`."""
    policy, critic = (np.float32, (task.policy_size,)), (np.float32, (task.critic_size,))
    out = {
        "policy_obs": policy,  # of the step (terminal where an episode ended)
        "critic_obs": critic,
        "reward": (np.float64, ()),
        "terminated": (np.bool_, ()),
        "truncated": (np.bool_, ()),
        "fall": (np.bool_, ()),
        "sim_unstable": (np.bool_, ()),
        "lin_vel_error": (np.float64, ()),
        "ang_vel_error": (np.float64, ()),
        "terms": (np.float64, (len(task.reward_names),)),
    }
    batch = {
        "force": (np.float64, (3,)),
        "command": (np.float64, (3,)),
        "policy_obs": policy,  # to act on next (after a reset where an episode ended)
        "critic_obs": critic,
        "next_command": (np.float64, (3,)),
        "terrain_level": (np.int64, ()),
    }
    return out, batch


STEP_OUTPUT_COLUMNS = StepOutput._fields
BATCH_STEP_COLUMNS = tuple(name for name in BatchStep._fields if name not in ("out", "reward_names"))
"""The fields of `StepOutput` and the array fields of `BatchStep` the shared block holds (`step_columns`)."""
_OUT = "out."
"""Prefix of the shared arrays of `StepOutput` fields."""


def _fields(n: int, task: LocomotionTask) -> Columns:
    """Every array of the shared block: dtype and shape, for n robots (derived from the step record)."""
    out, batch = step_columns(task)
    return {
        "actions": (np.float64, (n, task.robot.num_joints)),
        **{_OUT + name: (dtype, (n, *shape)) for name, (dtype, shape) in out.items()},
        **{name: (dtype, (n, *shape)) for name, (dtype, shape) in batch.items()},
    }


def _block_size(n: int, task: LocomotionTask) -> int:
    return sum(
        _aligned(np.dtype(dtype).itemsize * int(np.prod(shape))) for dtype, shape in _fields(n, task).values()
    )


def _aligned(size: int) -> int:
    return -(-size // 64) * 64


def _views(buffer: Any, n: int, task: LocomotionTask) -> dict[str, np.ndarray]:
    """Numpy views of each array of the shared block `buffer`."""
    views, offset = {}, 0
    for name, (dtype, shape) in _fields(n, task).items():
        count = int(np.prod(shape))
        views[name] = np.frombuffer(buffer, dtype=dtype, count=count, offset=offset).reshape(shape)
        offset += _aligned(np.dtype(dtype).itemsize * count)
    return views


def _write_step(shared: dict[str, np.ndarray], rows: slice, step: BatchStep) -> None:
    for name in STEP_OUTPUT_COLUMNS:
        shared[_OUT + name][rows] = getattr(step.out, name)
    for name in BATCH_STEP_COLUMNS:
        shared[name][rows] = getattr(step, name)


def _read_step(shared: dict[str, np.ndarray], reward_names: tuple[str, ...]) -> BatchStep:
    """The step of every robot from the shared block (copies: the block is written again next step)."""
    out = StepOutput(**{name: shared[_OUT + name].copy() for name in STEP_OUTPUT_COLUMNS})
    batch = {name: shared[name].copy() for name in BATCH_STEP_COLUMNS}
    return BatchStep(out, **batch, reward_names=reward_names)


def _handle(batch: ZerithBatch, shared: dict[str, np.ndarray], rows: tuple[int, int], message: bytes) -> bool:
    """Carry out one message (step, reset, scenario, level rule, close) on the slice of robots [rows);
    False: closed."""
    start, stop = rows
    mine = slice(start, stop)
    if message == _STEP:
        _write_step(shared, mine, batch.step(shared["actions"][mine]))
        return True
    command, payload = pickle.loads(message)
    if command == "close":
        batch.close()
        return False
    if command == "scenario":
        batch.set_scenario(payload)
        return True
    if command == "level rule":
        batch.set_level_rule(payload)
        return True
    ids, seeds, commands, tiles = payload  # reset: robot indices of this slice, counted from 0
    batch.seed(seeds)
    policy, critic = batch.reset(ids, commands, tiles)
    shared["policy_obs"][start + ids] = policy
    shared["critic_obs"][start + ids] = critic
    shared["next_command"][mine] = batch.commands
    return True


def _serve(
    conn: Connection,
    block: Any,
    num_robots: int,
    rows: tuple[int, int],
    options: ZerithOptions,
    physics_threads: int,
) -> None:
    """A worker's life: build its batch of robots [rows), then answer messages until `close`, or until
    the process that made it is gone without closing it (killed, or stopped by a signal it does not
    handle): forked workers inherit the pool's ends of the pipes, so they would never see them close."""
    maker = os.getppid()
    # Signals to the caller's process group (Ctrl-C, `timeout`, `kill -- -PGID`) are the caller's to handle:
    # it stops at its next step, saves, and closes the pool. A worker that took them would die first.
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    if hasattr(os, "setpgid"):
        os.setpgid(0, 0)
    try:
        shared = _views(block, num_robots, options.task)
        batch = ZerithBatch(rows[1] - rows[0], options, physics_threads, first_robot=rows[0])
    except BaseException:
        conn.send_bytes(pickle.dumps(traceback.format_exc()))
        return
    conn.send_bytes(_OK)
    going = True
    while going:
        try:
            while not conn.poll(_PARENT_CHECK_S):
                if os.getppid() != maker:
                    return
            message = conn.recv_bytes()
        except (EOFError, KeyboardInterrupt):
            break
        try:
            going = _handle(batch, shared, rows, message)
            conn.send_bytes(_OK)
        except BaseException:
            conn.send_bytes(pickle.dumps(traceback.format_exc()))


class WorkerPool:
    """`num_robots` robots in `workers + 1` contiguous slices: the first stepped by the calling process, the
    others by `workers` worker processes (the robots contract, `zerith_gym.core.contract.Robots`)."""

    def __init__(
        self, num_robots: int, options: ZerithOptions, workers: int, physics_threads: int = 1
    ) -> None:
        if not isinstance(workers, int | np.integer) or not 1 <= workers < num_robots:
            raise ValueError(
                f"workers must be an integer in [1, {num_robots - 1}] (with the calling process, at most one "
                f"slice per robot), got {workers!r}"
            )
        context = mp.get_context("fork" if "fork" in mp.get_all_start_methods() else "spawn")
        self.num_robots = num_robots
        self.scenario = options.resolved_scenario
        self._seeds: dict[int, np.random.Generator] = {}
        self._block = context.RawArray(ctypes.c_byte, _block_size(num_robots, options.task))
        self._shared = _views(self._block, num_robots, options.task)
        self._reward_names = options.task.reward_names
        bounds = np.linspace(0, num_robots, workers + 2).round().astype(int).tolist()
        self._rows = list(itertools.pairwise(bounds))  # slice 0: this process; slice k: worker k - 1
        self._conns: list[Connection] = []
        self._processes: list[mp.process.BaseProcess] = []
        for rows in self._rows[1:]:
            parent, child = context.Pipe()
            process = context.Process(
                target=_serve,
                args=(child, self._block, num_robots, rows, options, physics_threads),
                name=f"zerith-worker-{rows[0]}-{rows[1]}",
                daemon=True,
            )
            process.start()
            child.close()
            self._conns.append(parent)
            self._processes.append(process)
        self._finalizer = weakref.finalize(self, _shut_down, self._conns, self._processes)
        self._collect("starting", self._conns)
        rows = self._rows[0]
        self._local = ZerithBatch(rows[1] - rows[0], options, physics_threads)

    # ---------------------------------------------------------------------------------- ZerithBatch API
    def seed(self, seeds: Mapping[int, np.random.Generator]) -> None:
        """Give robots their random generators (robot index -> generator); used at their next reset."""
        self._seeds.update(seeds)

    def reset(
        self,
        ids: np.ndarray,
        commands: Mapping[int, np.ndarray] | None = None,
        tiles: Mapping[int, tuple[int, int]] | None = None,
    ) -> tuple[np.ndarray, np.ndarray]:
        """Start new episodes of robots `ids` (each in its slice, with its fixed command and start tile if
        given; see `ZerithBatch.reset`); returns their observations."""
        ids = np.asarray(ids)
        seeds, self._seeds = self._seeds, {}
        commands, tiles = dict(commands or {}), dict(tiles or {})
        messages = {}
        for k, (start, stop) in enumerate(self._rows):
            local = ids[(ids >= start) & (ids < stop)] - start
            local_seeds = {i - start: rng for i, rng in seeds.items() if start <= i < stop}
            if len(local) or local_seeds:
                local_commands = {i - start: c for i, c in commands.items() if start <= i < stop}
                local_tiles = {i - start: t for i, t in tiles.items() if start <= i < stop}
                payload = (local, local_seeds, local_commands, local_tiles)
                messages[k] = pickle.dumps(("reset", payload))
        self._run(messages, "resetting")
        return self._shared["policy_obs"][ids], self._shared["critic_obs"][ids]  # indexing by an array copies

    def set_scenario(self, scenario: Scenario) -> None:
        """Every slice follows `scenario` from now on (see `ZerithBatch.set_scenario`)."""
        check_scenario_change(self.scenario, scenario)
        message = pickle.dumps(("scenario", scenario))
        self._run(dict.fromkeys(range(len(self._rows)), message), "changing the scenario")
        self.scenario = scenario

    def set_level_rule(self, rule: LevelRule | None) -> None:
        """Every slice moves its robots between terrain levels by `rule` (`zerith_gym.terrain.levels`)."""
        self._local.set_level_rule(rule)  # checks the rule against the terrain before the workers see it
        message = pickle.dumps(("level rule", rule))
        self._run(dict.fromkeys(range(1, len(self._rows)), message), "setting the terrain curriculum")

    @property
    def commands(self) -> np.ndarray:
        """The current command of every robot, (n, 3)."""
        return self._shared["next_command"].copy()

    def step(self, actions: np.ndarray) -> BatchStep:
        """One control step of every robot (checked actions (n, 12)); robots whose episode ended restart."""
        shared = self._shared
        shared["actions"][:] = actions
        self._run(dict.fromkeys(range(len(self._rows)), _STEP), "stepping")
        return _read_step(shared, self._reward_names)

    def close(self) -> None:
        """Stop the worker processes (waiting for them to finish their current message)."""
        if self._finalizer.alive:
            self._local.close()
        self._finalizer()

    # ------------------------------------------------------------------------------------------------
    def _run(self, messages: dict[int, bytes], doing: str) -> None:
        """Send slice k its message, carry out slice 0's here meanwhile, then wait for every worker."""
        if not self._finalizer.alive:
            raise RuntimeError("the Zerith worker processes were closed (env.close()); make a new env")
        remote = []
        for k, message in messages.items():
            if k == 0:
                continue
            conn = self._conns[k - 1]
            try:
                conn.send_bytes(message)
            except OSError:
                self.close()
                raise RuntimeError(
                    f"a Zerith worker process exited (killed, or out of memory?) before {doing}"
                ) from None
            remote.append(conn)
        try:
            if 0 in messages:
                _handle(self._local, self._shared, self._rows[0], messages[0])
        finally:  # the workers' answers are read even if this slice failed, to keep the pipes in step
            self._collect(doing, remote)

    def _collect(self, doing: str, conns: list[Connection]) -> None:
        """Wait for the answers of `conns`; RuntimeError with the worker's traceback if one failed."""
        errors = []
        for conn in conns:
            try:
                answer = conn.recv_bytes()
            except (EOFError, OSError):
                errors.append("the worker process exited (killed, or out of memory?)")
                continue
            if answer != _OK:
                errors.append(pickle.loads(answer))
        if errors:
            self.close()
            raise RuntimeError(f"a Zerith worker process failed while {doing}:\n" + "\n".join(errors))


def _shut_down(conns: list[Connection], processes: list[mp.process.BaseProcess]) -> None:
    """Ask every worker to stop, then make sure it has."""
    for conn in conns:
        with contextlib.suppress(OSError, ValueError):
            conn.send_bytes(pickle.dumps(("close", None)))
    for process in processes:
        process.join(timeout=5)
        if process.is_alive():
            process.terminate()
            process.join(timeout=1)
    for conn in conns:
        conn.close()
