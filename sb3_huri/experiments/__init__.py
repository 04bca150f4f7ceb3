"""The paper's experiments: a grid of short runs, a campaign of long ones, and the pages their results make.

    python -m sb3_huri.experiments run --env Zerith1-v0 --methods huri huri-baseline --seeds 0 1 2 \\
        --timesteps 2000000 --eval-episodes 10 --out results/zerith [--backend local|ray] [--workers W]
    python -m sb3_huri.experiments report results/zerith
    python -m sb3_huri.experiments campaign [--status] [--max-wall-minutes M]
    python -m sb3_huri.experiments results

Every run of them is trained, checkpointed, evaluated and loaded by ``sb3_huri.runner``; these are the
drivers of many runs. Shared by them:

- ``statistics``: the interval estimates of every table (t, Wilson, paired Newcombe);
- ``paper``: the paper's own numbers, printed beside ours;
- ``errors``: ``ExperimentError``, which every command prints without a traceback.

Then one package per job, each listing its modules:

- ``grid``: methods x seeds of short runs (``run``, ``report``; docs/experiments.md);
- ``campaign``: the long runs' queue, its scheduler, final evaluations and the results page (``campaign``,
  ``results``; docs/campaign.md);
- ``analyses``: what the scripts of ``benchmarks/`` compute (robustness curves, agents compared on the same
  robots, survival by domain parameter, force exposure, single pushes, the expectation loss's fit).

From Python: ``run_experiment(out, env, methods, seeds, timesteps, ...)`` and ``write_report(out)``.
"""

from sb3_huri.experiments.errors import ExperimentError
from sb3_huri.experiments.grid.driver import run_experiment
from sb3_huri.experiments.grid.layout import EvalSettings
from sb3_huri.experiments.grid.report import write_report

__all__ = ["EvalSettings", "ExperimentError", "run_experiment", "write_report"]
