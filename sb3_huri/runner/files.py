"""Files a kill cannot tear: every file of a run is written whole through a temporary file, then renamed.

``replaced(path)`` gives a temporary path beside `path` to write to by any means (``model.save``,
``th.save``, ``np.savez`` on an open file); when the block ends without an error the temporary file is
flushed to disk and renamed onto `path` (``os.replace``: atomic on POSIX and Windows), and on an error it is
removed before anything else is done (a full disk gets its space back at once), and the error, an OSError,
names `path`. A kill at any moment leaves the old file or the new one, never half of one. ``link_or_copy``
puts a second name on a file (a hard link: no copy, no space) the same way.
"""

from __future__ import annotations

import contextlib
import functools
import json
import os
import shutil
import tempfile
from collections.abc import Iterator
from pathlib import Path
from typing import Any


class RunError(Exception):
    """A problem with a run's files or a request for it that the user has to resolve: a missing, corrupt or
    foreign file, or a request the run cannot meet. Commands print it without a traceback."""


@contextlib.contextmanager
def replaced(path: str | os.PathLike) -> Iterator[Path]:
    """A temporary path in `path`'s folder (created, with the suffix of `path`) that replaces `path` when
    the block ends without an error; removed otherwise, first of all, and an OSError re-raised naming
    `path` (the file that could not be written, not its temporary name)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    handle, name = tempfile.mkstemp(dir=path.parent, prefix=f".{path.stem}.", suffix=f".tmp{path.suffix}")
    os.close(handle)
    temporary = Path(name)
    try:
        os.chmod(temporary, 0o644)  # mkstemp gives 0600: other users of a shared folder could not read it
        yield temporary
        with open(temporary, "rb+") as written:  # on disk before the rename, so a crash keeps one whole file
            os.fsync(written.fileno())
        os.replace(temporary, path)
    except BaseException as error:
        with contextlib.suppress(OSError):
            os.unlink(temporary)
        if isinstance(error, OSError):
            raise naming(error, path) from error
        raise


def naming(error: OSError, path: str | os.PathLike) -> OSError:
    """`error` naming `path` as its file (an error of a write to an open file names none), of the same kind
    (``OSError(errno, ...)`` gives ``FileNotFoundError``, ``PermissionError``, ...); `error` itself when
    it has no error number or names `path` already."""
    if error.errno is None or error.filename == str(path):
        return error
    return OSError(error.errno, error.strerror or os.strerror(error.errno), str(path))


def link_or_copy(source: str | os.PathLike, target: str | os.PathLike) -> None:
    """`source`'s content under the name `target` too, replacing it whole: a hard link (no copy and no disk
    space; the files of a run are only ever replaced, never changed in place, so the two names stay
    independent), or a copy where the file system has no hard links."""
    source, target = Path(source), Path(target)
    if target.is_file() and os.path.samefile(source, target):
        return  # one file already (a rename onto another name of it would leave the temporary name)
    target.parent.mkdir(parents=True, exist_ok=True)
    temporary = target.with_name(f".{target.name}.link.tmp")
    with contextlib.suppress(FileNotFoundError):
        os.unlink(temporary)
    try:
        os.link(source, temporary)
    except OSError:
        with replaced(target) as copy:
            shutil.copyfile(source, copy)
        return
    try:
        os.replace(temporary, target)
    except OSError as error:
        with contextlib.suppress(OSError):
            os.unlink(temporary)
        raise naming(error, target) from error


def write_text(path: str | os.PathLike, text: str) -> None:
    """``text`` at `path`, atomically."""
    with replaced(path) as temporary:
        temporary.write_text(text)


def write_json(path: str | os.PathLike, data: Any) -> None:
    """``data`` as indented JSON with sorted keys at `path`, atomically."""
    write_text(path, json.dumps(data, indent=1, sort_keys=True) + "\n")


def read_json(path: Path, what: str) -> Any:
    """The JSON value at `path`; RunError naming `what` the file should hold if it is not JSON."""
    try:
        return json.loads(path.read_text())
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as error:
        raise RunError(f"{path} is corrupt ({error}); it should hold {what}") from error


def resumed_record(
    path: Path, record: dict[str, Any], same: tuple[str, ...], results: str, what: str
) -> dict[str, Any]:
    """A resumable measurement's `record` with the `results` (a mapping) and ``eval_s`` of the file at
    `path`, when that file measured with the same values of the keys `same`; `record` as it is without a
    file. RunError for a file that is not such a record (naming `what` it should hold) or that measured
    otherwise (naming the keys that differ)."""
    if not path.is_file():
        return record
    previous = read_json(path, what)
    if not isinstance(previous, dict) or not isinstance(previous.get(results), dict):
        raise RunError(f"{path} holds no {results}; delete it to measure anew")
    canonical = functools.partial(json.dumps, sort_keys=True)  # equal for a value and its copy read back
    differing = [key for key in same if canonical(previous.get(key)) != canonical(record[key])]
    if differing:
        raise RunError(
            f"{path} holds measurements with other {', '.join(differing)} "
            f"({'; '.join(f'{key}: {previous.get(key)}' for key in differing)}); measure with those, "
            "or delete the file to measure anew"
        )
    return {**record, results: previous[results], "eval_s": float(previous.get("eval_s", 0.0))}
