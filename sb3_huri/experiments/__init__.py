"""The paper's experiments: a grid of short runs, a campaign of long ones, and the pages their results make.

    python -m sb3_huri.experiments run --env Zerith1-v0 --methods huri huri-baseline --seeds 0 1 2 \\
        --timesteps 2000000 --eval-episodes 10 --out results/zerith [--backend local|ray] [--workers W]
    python -m sb3_huri.experiments report results/zerith
    python -m sb3_huri.experiments campaign [--status] [--max-wall-minutes M]
    python -m sb3_huri.experiments results

Modules, one job each. Shared by both:

- ``trainer``: the one trainer of every run: start or resume a run folder, checkpoint it between rollouts;
- ``evaluation``: the paper's protocol (Table 1 survival, velocity tracking, terrain tests of Tables 8/9,
  risk traces) on a trained agent;
- ``statistics``: the interval estimates of every table (t, Wilson, paired Newcombe);
- ``paper``: the paper's own numbers, printed beside ours;
- ``layout``: the grid's experiment folder (its settings, run folders and ``status.json``), and the
  ``ExperimentError`` and atomic writes every command uses.

The grid (``run``, ``report``):

- ``training``: one run of the grid trained on the env's preset, resumable from its last checkpoint;
- ``job``: one run's whole job (train, then evaluate), what a backend executes;
- ``backends``: a local process pool, or Ray tasks across a cluster;
- ``driver``: the ``run`` command: skip finished runs, hand the rest to a backend, print progress;
- ``report``: ``report.md`` and figures beside the paper's numbers.

The campaign (``campaign``, ``results``; docs/campaign.md):

- ``queue``: the long runs of ``runs/campaign.yml``, in priority order, and how far each has come;
- ``campaign``: trains the queue's unfinished entries, one per core, stretch after stretch;
- ``robustness``: a run's robustness rows (``robustness.csv``), a Table-1 mean every few million steps;
- ``final_evaluation``: an entry's final evaluation at its step, on 100 held-out robots;
- ``results`` (a package: tables, figures, the quadruped's and the rollout shape's sections):
  ``docs/results.md`` and its figures, generated from the queue and its run folders.

The analyses behind the scripts of ``benchmarks/`` (each script only parses its command line):

- ``robustness_curves`` and ``robustness_plot``: a long run's robustness curve from its kept checkpoints,
  its status, trend and shipping check (``<run>/robustness.md``), and its figure with forks and other
  methods beside it (``robustness_curve.py``);
- ``agents``: agents re-evaluated case by case, and two agents compared on the same robots
  (``eval_agents.py``, ``compare_agents.py``);
- ``domain_survival``: survival against the domain parameters each robot drew (``survival_by_domain.py``);
- ``force_exposure``: robot-steps and falls under each force of a training scenario (``force_exposure.py``);
- ``impulses``: survival of single pushes, and Table 1's pushes counted one by one (``impulse_envelope.py``);
- ``expectation_fit``: the expectation loss's two readings fitting a known distribution
  (``bench_expectation_loss.py``).

From Python: ``run_experiment(out, env, methods, seeds, timesteps, ...)`` and ``write_report(out)``.
"""

from sb3_huri.experiments.driver import run_experiment
from sb3_huri.experiments.layout import EvalSettings, ExperimentError
from sb3_huri.experiments.report import write_report

__all__ = ["EvalSettings", "ExperimentError", "run_experiment", "write_report"]
