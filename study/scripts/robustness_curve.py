"""The robustness learning curve of a long run: its checkpoints evaluated on the paper's Table-1 scenarios.

For every checkpoint of a run (`<run>/checkpoints/rl_model_<steps>_steps.zip` and its normalizer, written by
`examples/train_zerith.py`) at least `--every` steps after the previous row of the curve, and for the run's
newest model, evaluates the deterministic policy on the six Table-1 scenarios (continuous and sudden forces on
centroid, hands and feet, at the test ranges and 1 m/s), on `side-impact` (one 200 N push from the side),
`nominal@1.0` and `nominal@0.5`, and appends a
row per checkpoint to `<run>/robustness.csv`: steps, the run's training wall time at that step (from
`curve.csv`) and the hardware it trained on (`state.json`), the episodes per case, the survival rate of
each case (`--episodes` robots, seeds `--seed` + i, the same for every checkpoint), the Table-1 mean and
the mean forward velocity at 1 m/s. A row evaluated with another number of episodes is evaluated again
with `--episodes` when its checkpoint is still there, and kept as it is otherwise.

    python -m study.scripts.robustness_curve runs/huri/Zerith1-v0_1                 # new checkpoints only
    python -m study.scripts.robustness_curve runs/huri/Zerith1-v0_1 --every 5000000 --episodes 50
    python -m study.scripts.robustness_curve runs/huri/Zerith1-v0_1 --summary       # <run>/robustness.md too
    python -m study.scripts.robustness_curve runs/huri/Zerith1-v0_1 --plot docs/media/robust-run.png
    python -m study.scripts.robustness_curve runs/huri/Zerith1-v0_1 --plot curve.png \
        --forks runs/huri/Zerith1-v0_3 --versus runs/huri-baseline/Zerith1-v0_1    # PPO beside it

With `--summary`, the run's status (sessions, steps, wall time, curriculum, the update's figures) and the
robustness curve, with its trend and the shipping check, are written to `<run>/robustness.md`. The work is
done by `study.analyses.robustness_curves` and `study.analyses.robustness_plot`.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import torch as th

from study.analyses.robustness_curves import update_curve, write_summary
from study.analyses.robustness_plot import plot_curve


def main() -> None:
    """Parse the command line, update the run's curve, then write its summary and plot where asked."""
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("run", type=Path, help="a run folder written by examples/train_zerith.py")
    parser.add_argument(
        "--every", type=int, default=5_000_000, help="env steps between evaluated checkpoints"
    )
    parser.add_argument("--episodes", type=int, default=50, help="episodes per case (default 50)")
    parser.add_argument("--seed", type=int, default=1000)
    parser.add_argument(
        "--summary", action="store_true", help="also write the run's status and curve to <run>/robustness.md"
    )
    parser.add_argument("--plot", type=Path, default=None, help="also draw the curve into this image file")
    parser.add_argument(
        "--forks",
        type=Path,
        nargs="+",
        default=[],
        help="runs forked from this one: their Table-1 mean in the plot",
    )
    parser.add_argument(
        "--versus",
        type=Path,
        nargs="+",
        default=[],
        help="other methods' runs (e.g. PPO with the same recipe): their Table-1 mean in the plot, dashed",
    )
    args = parser.parse_args()
    th.set_num_threads(1)
    update_curve(args.run, args.every, args.episodes, args.seed)
    if args.summary:
        print(f"wrote {write_summary(args.run)}")
    if args.plot is not None:
        plot_curve(args.run, args.plot, tuple(args.forks), tuple(args.versus))


if __name__ == "__main__":
    main()
