"""``python -m sb3_huri.export``: export a run folder's actor to ONNX (see ``sb3_huri.export``)."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from pathlib import Path

import torch as th

import sb3_huri.export as package
from sb3_huri.export.graph import INPUT_NAME, OUTPUT_NAME, actor_of
from sb3_huri.export.metadata import training_scenario_of
from sb3_huri.export.onnx_file import check_export, export_actor
from sb3_huri.runner.folder import load_run
from zerith_gym import ZERITH1_ID


def main(argv: Sequence[str] | None = None) -> None:
    """Command line: export a run folder's actor, then check it against SB3 when ONNX Runtime is installed."""
    parser = argparse.ArgumentParser(
        prog="python -m sb3_huri.export",
        description=package.__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument(
        "run", type=Path, help="run folder in RL Zoo's layout (<env>.zip, <env>/vecnormalize.pkl)"
    )
    parser.add_argument(
        "--env", default=ZERITH1_ID, help=f"environment id of the run (default: {ZERITH1_ID})"
    )
    parser.add_argument("--output", "-o", type=Path, required=True, help="the ONNX file to write")
    parser.add_argument(
        "--unnormalized",
        action="store_true",
        help="the run was trained without VecNormalize (no statistics file)",
    )
    args = parser.parse_args(argv)
    th.set_num_threads(1)
    try:
        import onnx  # noqa: F401
    except ImportError:
        parser.exit(2, "error: the onnx package is needed to export: pip install 'sb3-huri[deploy]'\n")
    try:
        model, normalizer = load_run(args.run, args.env, normalized=not args.unnormalized)
        run = args.run.resolve()
        export_actor(
            model,
            normalizer,
            args.env,
            args.output,
            f"{run.parent.name}/{run.name}",
            training_scenario_of(run, args.env),
        )
    except (FileNotFoundError, ValueError) as error:
        parser.exit(2, f"error: {error}\n")
    actor = actor_of(model.policy)
    entry = f"the '{actor.key}' entry, " if actor.key else ""
    normalized = "normalized in the graph" if normalizer is not None else "not normalized"
    size = args.output.stat().st_size / 1024
    print(
        f"wrote {args.output} ({size:.0f} KiB): {INPUT_NAME} (batch, {actor.input_size}) raw observation "
        f"({entry}{normalized}) -> {OUTPUT_NAME} (batch, {len(actor.low)})"
    )
    try:
        import onnxruntime  # noqa: F401
    except ImportError:
        print("onnxruntime is not installed: the export was not checked against SB3's predict")
        return
    difference = check_export(args.output, model, normalizer)
    print(f"checked with ONNX Runtime: largest difference to SB3's predict {difference:.1e}")
    if difference > 1e-4:
        parser.exit(1, "error: the exported actor does not match the model\n")


if __name__ == "__main__":
    main(sys.argv[1:])
