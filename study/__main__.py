"""Command line of the study: ``python -m study campaign ...`` and ``python -m study results``.

    python -m study campaign [--status] [--slots N] [--max-wall-minutes 150]
    python -m study results

``campaign`` trains the long runs of the queue ``runs/campaign.yml`` in the background, stretch after stretch,
resumable (``study.campaign.scheduler``); ``results`` writes ``docs/results.md`` and its figures from the
queue's run folders (``study.results``). Both run from the repository's root.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from sb3_huri.experiments.errors import ExperimentError
from sb3_huri.runner.files import RunError
from study.campaign.queue import DEFAULT_QUEUE


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="python -m study", description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    commands = parser.add_subparsers(dest="command", required=True)
    campaign = commands.add_parser("campaign", help="train the campaign's queue (resumable), or --status")
    campaign.add_argument("--queue", type=Path, default=DEFAULT_QUEUE, help="the queue file")
    campaign.add_argument("--slots", type=int, default=None, help="entries at once (default: one per core)")
    campaign.add_argument(
        "--max-wall-minutes", type=float, default=None, help="stop, with checkpoints, after"
    )
    campaign.add_argument("--status", action="store_true", help="print where every entry stands, and exit")
    campaign.add_argument("--entry", default=None, help="train and evaluate this one entry in this process")
    campaign.add_argument(
        "--parent",
        type=int,
        default=None,
        help="with --entry: stop, with a checkpoint, when process PARENT ends",
    )
    results = commands.add_parser("results", help="write docs/results.md and its figures from the runs")
    results.add_argument("--queue", type=Path, default=DEFAULT_QUEUE, help="the queue file")
    results.add_argument("--out", type=Path, default=Path("docs/results.md"), help="the page to write")
    return parser


def _campaign(args: argparse.Namespace) -> int:
    """The ``campaign`` command: status, one entry, or the whole queue; 0 when nothing is left to do."""
    from study.campaign.child import run_child
    from study.campaign.queue import load_queue
    from study.campaign.scheduler import run_campaign, status_table

    max_wall_s = None if args.max_wall_minutes is None else 60.0 * args.max_wall_minutes
    if args.status:
        print(status_table(args.queue))
        return 0
    if args.entry is not None:
        entries = {entry.name: entry for entry in load_queue(args.queue)}
        if args.entry not in entries:
            raise ExperimentError(f"no entry {args.entry!r} in {args.queue}; entries: {', '.join(entries)}")
        return run_child(entries[args.entry], max_wall_s, args.parent)
    unfinished = run_campaign(args.queue, args.slots, max_wall_s)
    print(f"{len(unfinished)} entries unfinished" if unfinished else "every entry is done")
    return 1 if unfinished else 0


def main(argv: list[str] | None = None) -> int:
    """Run the command line; returns the exit status (0: nothing left to do, 1: entries unfinished, 2: an
    error to resolve)."""
    args = _parser().parse_args(argv)
    try:
        if args.command == "campaign":
            return _campaign(args)
        from study.results import write_results

        print(f"wrote {write_results(args.queue, args.out)}")
        return 0
    except RunError as error:
        print(f"error: {error}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        return 130


if __name__ == "__main__":
    sys.exit(main())
