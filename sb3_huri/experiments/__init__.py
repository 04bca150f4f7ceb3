"""Experiments on your own runs: a grid of methods x seeds, trained, evaluated and reported.

    python -m sb3_huri.experiments run --env Zerith1-v0 --methods huri huri-baseline --seeds 0 1 2 \\
        --timesteps 2000000 --eval-episodes 10 --out results/zerith [--backend local|ray] [--workers W]
    python -m sb3_huri.experiments report results/zerith

Every run is trained, checkpointed, evaluated and loaded by ``sb3_huri.runner``; the grid drives many of
them (``grid``, docs/experiments.md). Beside it:

- ``statistics``: the interval estimates of every table (t, Wilson, paired Newcombe, IQM, P(A > B));
- ``paper``: the paper's own numbers, printed beside ours;
- ``errors``: ``ExperimentError``, which every command prints without a traceback.

From Python: ``run_experiment(out, env, methods, seeds, timesteps, ...)`` and ``write_report(out)``.
"""

from sb3_huri.experiments.errors import ExperimentError
from sb3_huri.experiments.grid.driver import run_experiment
from sb3_huri.experiments.grid.layout import EvalSettings
from sb3_huri.experiments.grid.report import write_report

__all__ = ["EvalSettings", "ExperimentError", "run_experiment", "write_report"]
