"""The campaign: the project's long runs in one resumable queue, trained one per core in the background of
every sitting, and the results page generated from them (``python -m study campaign`` and
``results``; docs/campaign.md).

- ``queue``: the long runs of ``runs/campaign.yml``, in priority order, and how far each has come;
- ``scheduler``: trains the queue's unfinished entries, one per core, stretch after stretch;
- ``final_evaluation``: an entry's final evaluation at its step, on 100 held-out robots;
- ``analyses``: what an evaluated entry is measured on then: its risk levels and its survival over force
  magnitude;
- ``results`` (a package: tables, figures, the quadruped's and the rollout shape's sections):
  ``docs/results.md`` and its figures, generated from the queue and its run folders.
"""
