"""Command line: ``python -m sb3_huri.experiments run ...`` and ``python -m sb3_huri.experiments report DIR``.

    python -m sb3_huri.experiments run --env Zerith1-v0 \\
        --methods huri huri-baseline huri-cvar0.5 huri-no-rnd huri-no-iqr huri-cvar \\
        --seeds 0 1 2 3 4 --timesteps 4000000 --eval-episodes 10 --out results/zerith
    python -m sb3_huri.experiments report results/zerith

``run`` trains every method x seed (RL Zoo layout per run, the env's preset and its curriculum, the batched
env) and evaluates each under the paper's protocol; stopped at any point, the same command continues every
unfinished run from its last checkpoint and skips the finished ones. ``--backend ray`` runs the same runs as
Ray tasks on the cluster of ``RAY_ADDRESS`` (or ``--ray-address``), with the output folder shared by its
machines. ``report`` writes ``DIR/report.md`` with the tables, figures and the paper's numbers. A standard
Gymnasium task (``--env Walker2d-v5``) trains its preset as RL Zoo does and is evaluated on its return; its
``report`` (of a task's folder, or a folder of them) gives means, IQMs and the probability of beating PPO.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from sb3_huri.experiments.grid.layout import EvalSettings
from sb3_huri.runner.files import RunError


def _parser() -> argparse.ArgumentParser:
    from sb3_huri.zoo import METHODS

    parser = argparse.ArgumentParser(
        prog="python -m sb3_huri.experiments",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    commands = parser.add_subparsers(dest="command", required=True)
    run = commands.add_parser("run", help="train and evaluate a grid of methods x seeds (resumable)")
    run.add_argument(
        "--env", default="Zerith1-v0", help="env id: a Zerith env (default Zerith1-v0) or a standard task"
    )
    run.add_argument(
        "--methods", nargs="+", default=list(METHODS), help=f"methods (default: all): {', '.join(METHODS)}"
    )
    run.add_argument("--seeds", nargs="+", type=int, default=[0, 1, 2], help="training seeds")
    run.add_argument("--timesteps", type=int, required=True, help="env steps per run")
    run.add_argument("--eval-episodes", type=int, default=10, help="episodes per evaluation case")
    run.add_argument("--eval-episode-steps", type=int, default=1000, help="evaluation time limit (steps)")
    run.add_argument("--eval-seed", type=int, default=1000, help="seed of the evaluation robots")
    run.add_argument("--out", type=Path, required=True, help="experiment folder (created, or continued)")
    run.add_argument("--backend", choices=("local", "ray"), default="local", help="where runs execute")
    run.add_argument("--workers", type=int, default=None, help="runs at once (local: one per core; ray: all)")
    run.add_argument(
        "--cpus-per-run",
        type=int,
        default=None,
        help="cores per run, used by its robots' worker processes (local: cores / --workers; ray: 1)",
    )
    run.add_argument("--ray-address", default=None, help="Ray cluster (default: RAY_ADDRESS or local)")
    run.add_argument(
        "-conf", "--conf-file", type=Path, default=None, help="RL Zoo hyperparameter file (default: huri.yml)"
    )
    run.add_argument(
        "--checkpoint-freq", type=int, default=50_000, help="env steps between checkpoints (default 50000)"
    )
    report = commands.add_parser("report", help="write DIR/report.md and the figures")
    report.add_argument("out", type=Path, help="experiment folder (or a folder of standard tasks' ones)")
    return parser


def main(argv: list[str] | None = None) -> int:
    """Run the command line; returns the exit status (0: every run done, 1: some not, 2: a usage error)."""
    args = _parser().parse_args(argv)
    try:
        if args.command == "report":
            from sb3_huri.experiments.grid.report import write_report

            path = write_report(args.out)
            print(f"wrote {path}")
            return 0
        from sb3_huri.experiments.grid.driver import run_experiment

        outcomes = run_experiment(
            args.out,
            args.env,
            args.methods,
            args.seeds,
            args.timesteps,
            EvalSettings(
                episodes=args.eval_episodes, seed=args.eval_seed, episode_steps=args.eval_episode_steps
            ),
            backend=args.backend,
            parallel=args.workers,
            cpus_per_run=args.cpus_per_run,
            conf=args.conf_file,
            checkpoint_freq=args.checkpoint_freq,
            ray_address=args.ray_address,
        )
    except RunError as error:
        print(f"error: {error}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        return 130
    unfinished = [o for o in outcomes if o.state != "done"]
    if unfinished:
        print(f"{len(unfinished)} run(s) not finished; run the same command again to continue them")
        return 1
    print(f"all {len(outcomes)} runs done; report: python -m sb3_huri.experiments report {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
