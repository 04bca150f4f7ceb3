"""A fixed stepping loop of `ZerithVecEnv` from a given checkout, to time two versions side by side.

    farm-bench -n 7 --timeout 600 --vs "python benchmarks/step_loop.py ../before" -- \\
        python benchmarks/step_loop.py .

Imports `zerith_gym` from the checkout given as the first argument, builds 32 robots in `train` (no worker
processes) and steps them 400 times with the same uniform random actions. farm-bench times the whole
process and gives the after / before ratio pair by pair (docs/performance.md).
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

checkout = str(Path(sys.argv[1]).resolve())
sys.path.insert(0, checkout)
import zerith_gym  # noqa: E402

assert zerith_gym.__file__.startswith(checkout), f"zerith_gym came from {zerith_gym.__file__}"
env = zerith_gym.make_vec_env(32, seed=0, scenario="train", workers=0)
env.reset()
for actions in np.random.default_rng(0).uniform(-0.2, 0.2, (400, 32, 12)):
    env.step(actions)
env.close()
