"""The analyses behind the scripts of ``study/scripts/`` (each script only parses its command line):

- ``robustness_curves`` and ``robustness_plot``: a long run's robustness curve from its kept checkpoints,
  its status, trend and shipping check (``<run>/robustness.md``), and its figure with forks and other
  methods beside it (``robustness_curve.py``);
- ``agents``: agents re-evaluated case by case, and two agents compared on the same robots
  (``eval_agents.py``, ``compare_agents.py``);
- ``domain_survival``: survival against the domain parameters each robot drew (``survival_by_domain.py``);
- ``force_exposure``: robot-steps and falls under each force of a training scenario (``force_exposure.py``);
- ``impulses``: survival of single pushes, and Table 1's pushes counted one by one (``impulse_envelope.py``);
- ``expectation_fit``: the expectation loss's two readings fitting a known distribution
  (``expectation_loss.py``);
- ``risk_levels``: the risk levels a HuRi agent's critic sets on the states it visits, per scenario: shares
  of states below, within and above its IQR band, beta and its RND part (``risk_levels.py``);
- ``force_magnitude``: survival over the force's magnitude in the Table-1 and Fig. 4 cases, under both
  readings of the forces on hands and feet and both hold times of a push (``force_magnitude.py``);
- ``advantages``: how far a HuRi agent's risk distortion moves the advantages of its own training rollouts
  from those of a neutral and of a constant risk level (``advantages.py``);
- ``command_line``: the arguments and loop of the scripts that measure run folders.
"""
