"""The campaign's child process: one entry trained, evaluated and measured, and why it stopped if it failed.

``python -m study campaign --entry NAME --parent PID`` runs ``run_child``: it ends with the
campaign that started it (``sb3_huri.runner.lock.die_with_parent``: a SIGTERM, which stops the training
after the rollout under way with a checkpoint), holds the entry's run folder for the whole entry, and on a
failure writes one line of why (``<file>: [Errno 28] No space left on device``) into the run folder's
``.failure.json`` (git-ignored) for the campaign's output and ``--status``. Its exit status tells the
campaign what to do next:

- 0: the entry is done; 1: unfinished (stopped, or an error a second start may get past);
- ``EXIT_LEFT``: an error that a second start would meet again (a full disk, an exceeded quota, a read-only
  file system, a file of the run that does not read: ``lasting``): the campaign leaves the entry alone at
  once, its last good checkpoint kept, and the next campaign, once the cause is gone, resumes from it;
- ``EXIT_BUSY``: another process holds the run folder (a trainer still stopping): not a failure, the
  campaign starts the entry again once the folder is free.
"""

from __future__ import annotations

import contextlib
import errno
import json
import os
import sys
import time
import traceback
from pathlib import Path
from typing import Any

from sb3_huri.runner.files import RunError, write_json
from sb3_huri.runner.lock import RunBusy, hold_run
from study.campaign.queue import CampaignEntry

EXIT_LEFT = 3
"""The child's exit status for an error that starting the entry again would meet again."""
EXIT_BUSY = 75
"""The child's exit status when another process holds the entry's run folder (``EX_TEMPFAIL``)."""
FAILURE_FILE = ".failure.json"
"""The note, in the run folder, of why its entry's last child failed (removed when the next one starts)."""
LASTING_ERRNOS = frozenset({errno.ENOSPC, errno.EDQUOT, errno.EROFS})
"""Errors of a write that no retry gets past until someone makes room or makes the disk writable."""


def lasting(error: BaseException) -> bool:
    """Whether starting the entry again would meet `error` again: a full disk, an exceeded quota, a
    read-only file system, or a RunError (a file or request the user has to resolve)."""
    if isinstance(error, RunBusy):
        return False
    return isinstance(error, RunError) or (isinstance(error, OSError) and error.errno in LASTING_ERRNOS)


def describe(error: BaseException) -> str:
    """`error` in one line: ``<file>: [Errno N] <reason>`` for an OSError of a file, its message for a
    RunError, its kind and message otherwise."""
    if isinstance(error, OSError) and error.errno is not None and error.filename:
        return f"{error.filename}: [Errno {error.errno}] {error.strerror}"
    if isinstance(error, RunError):
        return str(error)
    return f"{type(error).__name__}: {error}".splitlines()[0]


def run_child(entry: CampaignEntry, max_wall_s: float | None = None, parent: int | None = None) -> int:
    """Run `entry` in this process (``progress.run_entry``) as the campaign's child: gone with the process
    `parent` (None: not watched), its run folder held, a failure noted; returns the exit status."""
    from sb3_huri.runner.lock import die_with_parent
    from study.campaign.progress import run_entry

    if parent is not None:
        die_with_parent(parent)
    try:
        with hold_run(entry.run):
            (entry.run / FAILURE_FILE).unlink(missing_ok=True)
            return 0 if run_entry(entry, max_wall_s) == "done" else 1
    except RunBusy as error:
        _say(entry, str(error))
        return EXIT_BUSY
    except Exception as error:
        if not isinstance(error, RunError):
            with contextlib.suppress(OSError):
                traceback.print_exc()
        left = lasting(error)
        _say(entry, describe(error))
        note_failure(entry, describe(error), left)
        return EXIT_LEFT if left else 1


def _say(entry: CampaignEntry, line: str) -> None:
    """A line in the child's log (which may not be writable: a full disk)."""
    with contextlib.suppress(OSError):
        print(f"campaign entry {entry.name}: {line}", file=sys.stderr, flush=True)


def note_failure(entry: CampaignEntry, error: str, lasting: bool) -> None:
    """Write why the entry's child failed into its run folder's ``.failure.json`` (with this process's
    pid, to be told from an older note); nothing where that cannot be written either."""
    note = {"entry": entry.name, "pid": os.getpid(), "error": error, "lasting": lasting,
            "when": time.strftime("%Y-%m-%d %H:%M:%S")}  # fmt: skip
    with contextlib.suppress(OSError):
        write_json(entry.run / FAILURE_FILE, note)


def read_failure(entry: CampaignEntry, pid: int | None = None) -> dict[str, Any] | None:
    """The note of why the entry's last child failed, if there is one about this entry (and, given `pid`,
    written by that process)."""
    path = Path(entry.run) / FAILURE_FILE
    try:
        note = json.loads(path.read_text())
    except (OSError, ValueError):
        return None
    about = isinstance(note, dict) and note.get("entry") == entry.name and isinstance(note.get("error"), str)
    return note if about and (pid is None or note.get("pid") == pid) else None
