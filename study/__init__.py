"""This repository's own study of HuRi against PPO and its ablations, kept beside the installed packages.

Run from the repository's root (``python -m study campaign``, ``python -m study results``,
``python -m study.scripts.<name>``); it is not installed with ``sb3_huri`` and ``zerith_gym``, whose public
API it uses (``sb3_huri.runner`` trains, checkpoints and evaluates every run).

- ``campaign``: the long runs' queue (``runs/campaign.yml``), its scheduler, their final evaluations and
  the analyses measured after each (docs/campaign.md);
- ``results``: the results page, ``docs/results.md``, and its figures, generated from the queue's runs;
- ``analyses`` and ``scripts``: what is measured on trained agents, and the command line of each measure;
- ``device``: the shell scripts of a lent GPU machine; ``tests``: the study's tests.
"""
