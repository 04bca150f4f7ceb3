"""One writer per run folder, and trainers that end with the process that started them.

``hold_run(run)`` holds an exclusive lock (``fcntl.flock``) on ``<run>/.lock`` for as long as the block
runs, and writes the holder's pid into the file. The OS releases the lock when its holder dies, however it
dies (a ``kill -9`` or an out-of-memory kill included), so a lock left by a dead trainer never needs
clearing. A second holder of the same folder, in another process, is refused with ``RunBusy`` naming the
folder and the holder's pid, before it writes anything; in the same process the lock nests (the campaign's
child holds it for its whole entry, its ``train_run`` inside). Processes forked by the holder (its env
workers) close their copy of the lock file at once, so that the lock ends with the holder itself.

``die_with_parent(parent)`` makes this process get SIGTERM when `parent` is gone (Linux's parent-death
signal, and a thread that checks every second everywhere), which a trainer takes as a stop with a
checkpoint: a campaign killed alone leaves no trainer writing its folders beside the next campaign's.
"""

from __future__ import annotations

import contextlib
import ctypes
import os
import signal
import sys
import threading
import time
from collections.abc import Iterator
from pathlib import Path

from sb3_huri.runner.files import RunError

try:
    import fcntl
except ImportError:  # Windows: no folder lock
    fcntl = None  # type: ignore[assignment]

LOCK_FILE = ".lock"
"""The lock file of a run folder (git-ignored); it holds the pid of the process that holds the lock."""
PARENT_CHECK_S = 1.0
"""How often (s) a process started by the campaign checks that the campaign is still there."""

_held: dict[Path, tuple[int, int]] = {}
"""The folders this process holds: open lock file and nesting depth."""
_registry = threading.Lock()


def _forget_in_child() -> None:
    """In a process forked from a holder: close its copies of the lock files, without releasing the locks
    (the holder's), so that they end with the holder and not with its last env worker."""
    for descriptor, _ in _held.values():
        with contextlib.suppress(OSError):
            os.close(descriptor)
    _held.clear()


if hasattr(os, "register_at_fork"):
    os.register_at_fork(after_in_child=_forget_in_child)


class RunBusy(RunError):
    """Another process holds the run folder's lock: it trains (or evaluates) the folder now."""


@contextlib.contextmanager
def hold_run(run: str | os.PathLike) -> Iterator[None]:
    """Hold the run folder's lock for the block (created with the folder if need be); ``RunBusy`` naming
    the folder and the holder's pid if another process holds it. Nested holds in one process are one."""
    folder = Path(run).resolve()
    with _registry:
        descriptor, depth = _held.get(folder) or (_lock(folder), 0)
        _held[folder] = (descriptor, depth + 1)
    try:
        yield
    finally:
        with _registry:
            descriptor, depth = _held.pop(folder)
            if depth > 1:
                _held[folder] = (descriptor, depth - 1)
            else:
                _unlock(descriptor)


def _lock(folder: Path) -> int:
    """The open lock file of `folder`, locked, with this process's pid in it; ``RunBusy`` if held."""
    folder.mkdir(parents=True, exist_ok=True)
    descriptor = os.open(folder / LOCK_FILE, os.O_RDWR | os.O_CREAT | getattr(os, "O_CLOEXEC", 0), 0o644)
    if fcntl is None:
        return descriptor
    try:
        fcntl.flock(descriptor, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        pid = _pid_in(descriptor)
        os.close(descriptor)
        raise RunBusy(
            f"{folder} is held by another process (pid {pid or 'unknown'}, in {folder / LOCK_FILE}): one "
            "trainer per run folder; wait until it stops, or stop it"
        ) from None
    try:
        os.ftruncate(descriptor, 0)
        os.pwrite(descriptor, f"{os.getpid()}\n".encode(), 0)
    except OSError:
        _unlock(descriptor)
        raise
    return descriptor


def _unlock(descriptor: int) -> None:
    """Release and close a lock file (released first: forked workers share the open file until they end)."""
    if fcntl is not None:
        with contextlib.suppress(OSError):
            fcntl.flock(descriptor, fcntl.LOCK_UN)
    os.close(descriptor)


def _pid_in(descriptor: int) -> int | None:
    """The pid a lock file holds, or None (empty: its holder has not written it yet)."""
    text = os.pread(descriptor, 32, 0).decode(errors="replace").strip()
    return int(text) if text.isdigit() else None


def holder(run: str | os.PathLike) -> int | None:
    """The pid of the process holding the run folder's lock (this process's own if it holds it), or None
    when nobody does. Reads only: a folder without a lock file is free, and none is created."""
    folder = Path(run).resolve()
    if folder in _held:
        return os.getpid()
    if fcntl is None:
        return None
    try:
        descriptor = os.open(folder / LOCK_FILE, os.O_RDONLY | getattr(os, "O_CLOEXEC", 0))
    except FileNotFoundError:
        return None
    try:
        fcntl.flock(descriptor, fcntl.LOCK_SH | fcntl.LOCK_NB)
    except BlockingIOError:
        return _pid_in(descriptor) or -1
    else:
        fcntl.flock(descriptor, fcntl.LOCK_UN)
        return None
    finally:
        os.close(descriptor)


def die_with_parent(parent: int) -> None:
    """Get SIGTERM when the process `parent` is gone: at once if it is gone already (it may die before this
    call), from the OS when it dies (Linux), and from a daemon thread that checks every `PARENT_CHECK_S`
    seconds and repeats the signal until this process ends (a SIGTERM a trainer takes as a stop request
    ends it after the rollout under way, with a checkpoint; one elsewhere ends it at once)."""
    _parent_death_signal(signal.SIGTERM)
    if os.getppid() != parent:
        os.kill(os.getpid(), signal.SIGTERM)
    threading.Thread(target=_watch_parent, args=(parent,), name="parent-watch", daemon=True).start()


def _parent_death_signal(signum: int) -> bool:
    """Ask the OS to send `signum` when this process's parent dies (Linux's ``PR_SET_PDEATHSIG``); False
    where it cannot."""
    if not sys.platform.startswith("linux"):
        return False
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        return libc.prctl(1, signum, 0, 0, 0) == 0  # 1: PR_SET_PDEATHSIG
    except (OSError, AttributeError):
        return False


def _watch_parent(parent: int) -> None:
    """Wait until this process's parent is no longer `parent`, then send SIGTERM to this process every
    `PARENT_CHECK_S` seconds until it ends."""
    while os.getppid() == parent:
        time.sleep(PARENT_CHECK_S)
    while True:
        os.kill(os.getpid(), signal.SIGTERM)
        time.sleep(PARENT_CHECK_S)
