"""What the scripts that measure campaign run folders share (``study.scripts.risk_levels``,
``study.scripts.advantages``): their first arguments, and the loop that measures each folder and prints it."""

from __future__ import annotations

import argparse
from collections.abc import Callable, Sequence
from pathlib import Path

from sb3_huri.runner.files import RunError


def runs_parser(description: str, seed: int) -> argparse.ArgumentParser:
    """A parser of run folders, ``--steps`` (the first model at or after them) and ``--seed``."""
    parser = argparse.ArgumentParser(
        description=description, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("runs", type=Path, nargs="+", help="run folders of the campaign")
    parser.add_argument("--steps", type=int, default=None, help="the first model at or after these steps")
    parser.add_argument("--seed", type=int, default=seed, help="robot i is seeded seed + i")
    return parser


def measure_runs(
    parser: argparse.ArgumentParser,
    runs: Sequence[Path],
    measure: Callable[[Path], Path],
    text: Callable[[Path], str],
) -> None:
    """Measure each run folder with ``measure`` (one torch thread) and print ``text`` of the file it wrote;
    a missing folder is a usage error before anything runs, a ``RunError`` ends the command with its
    message."""
    import torch as th

    missing = [str(run) for run in runs if not run.is_dir()]
    if missing:
        parser.error(f"no such run folder: {', '.join(missing)}")
    th.set_num_threads(1)
    for run in runs:
        try:
            path = measure(run)
        except RunError as error:
            parser.exit(1, f"{error}\n")
        print(f"\n{text(path)}\n", flush=True)
