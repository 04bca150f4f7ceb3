"""The grid: methods x seeds of short runs, trained, evaluated and reported by one resumable command
(``python -m sb3_huri.experiments run`` and ``report``; docs/experiments.md).

- ``layout``: the experiment folder: its settings, the grid, each run's folder, ``status.json`` and lock;
- ``training``: one run of the grid trained on the env's preset, resumable from its last checkpoint;
- ``evaluation``: one run's checkpoint evaluated into its record (``sb3_huri.runner.record``);
- ``job``: one run's whole job (train, then evaluate), what a backend executes;
- ``backends``: a local process pool, or Ray tasks across a cluster;
- ``driver``: the ``run`` command: skip finished runs, hand the rest to a backend, print progress;
- ``report``: ``report.md`` and figures beside the paper's numbers;
- ``standard``, ``standard_report``: a standard Gymnasium task (``Walker2d-v5``, ...) instead of a Zerith env:
  its runs trained as RL Zoo trains them and evaluated on the task's return, and their report (means, IQMs,
  the probability of beating PPO over seeds).
"""
