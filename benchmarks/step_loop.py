"""A fixed stepping (or training) loop of `ZerithVecEnv` from a checkout, to time two versions side by side.

    farm-bench -n 7 --timeout 600 --vs "python benchmarks/step_loop.py ../before" -- \\
        python benchmarks/step_loop.py .
    farm-bench -n 5 --timeout 900 --vs "python benchmarks/step_loop.py ../before train" -- \\
        python benchmarks/step_loop.py . train

Imports `zerith_gym` and `sb3_huri` from the checkout given as the first argument and builds 32 robots in
`train` (no worker processes). Without a second argument it steps them 400 times with the same uniform random
actions; with `train`, HuRiPPO trains on them for 4 iterations of 64 steps (2 minibatches, 5 epochs, the
paper's networks), seed 0. farm-bench times the whole process and gives the after / before ratio pair by
pair (docs/performance.md).
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import torch as th

checkout = str(Path(sys.argv[1]).resolve())
sys.path.insert(0, checkout)
import sb3_huri  # noqa: E402
import zerith_gym  # noqa: E402

for package in (zerith_gym, sb3_huri):
    assert package.__file__.startswith(checkout), f"{package.__name__} came from {package.__file__}"
env = zerith_gym.make_vec_env(32, seed=0, scenario="train", workers=0)
if sys.argv[2:] == ["train"]:
    # every shared argument stated, so that checkouts from before and after HuRiPPO took PPO's defaults agree
    network = dict(net_arch=[512, 256, 128], activation_fn=th.nn.ELU)
    model = sb3_huri.HuRiPPO(
        "MultiInputPolicy", env, n_steps=64, batch_size=1024, n_epochs=5, learning_rate=2e-4, ent_coef=0.01,
        vf_coef=1.0, max_grad_norm=1.0, policy_kwargs=network, seed=0,
    )  # fmt: skip
    model.learn(4 * 64 * 32)
else:
    env.reset()
    for actions in np.random.default_rng(0).uniform(-0.2, 0.2, (400, 32, 12)):
        env.step(actions)
env.close()
