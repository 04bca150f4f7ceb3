"""Learning sanity check: HuRiPPO (``huri``) against PPO (``huri-baseline``), same budget, several seeds.

Both algorithms share every setting below (networks, rollout and update sizes, learning rate,
``VecNormalize`` with observation and reward normalization); only ``method`` differs. ``huri-baseline`` is
PPO with the same asymmetric networks and a scalar critic (its rollouts equal SB3 PPO's: see the tests).
Each run is scored by a deterministic evaluation of the final policy (10 episodes, unnormalized reward).

    nice -n 10 python benchmarks/bench_learning.py                     # Pendulum-v1 and HalfCheetah-v5
    python benchmarks/bench_learning.py --envs Pendulum-v1 --methods huri huri-baseline huri-cvar0.5
    python benchmarks/bench_learning.py --envs Pendulum-v1 --methods huri-percentile --td-level step
"""

import argparse
import json
import statistics
import time

import numpy as np
import torch as th
from stable_baselines3.common.env_util import make_vec_env
from stable_baselines3.common.evaluation import evaluate_policy
from stable_baselines3.common.vec_env import VecNormalize
from torch import nn

from sb3_huri import METHODS, HuRiPPO

PAPER_UPDATE = dict(
    n_minibatches=4,
    n_epochs=8,
    vf_coef=1.0,
    max_grad_norm=1.0,
    policy_kwargs=dict(net_arch=[512, 256, 128], activation_fn=nn.ELU),
)
"""The paper's update structure and networks (Table 3), which the measured table in docs/huri.md used."""

# Settings shared by all methods, per environment, sized for a small CPU budget.
SETTINGS = {
    "Pendulum-v1": dict(
        timesteps=100_000,
        n_envs=8,
        hyperparams=dict(
            PAPER_UPDATE,
            n_steps=256,
            gamma=0.9,
            learning_rate=1e-3,
            ent_coef=0.0,
            use_sde=True,
            sde_sample_freq=4,
        ),
    ),
    "HalfCheetah-v5": dict(
        timesteps=150_000,
        n_envs=4,
        hyperparams=dict(PAPER_UPDATE, n_steps=512, learning_rate=3e-4, ent_coef=0.0),
    ),
}


def run(env_id: str, method: str, seed: int, timesteps: int | None, td_level: str | None = None) -> dict:
    settings = SETTINGS[env_id]
    env = VecNormalize(make_vec_env(env_id, n_envs=settings["n_envs"], seed=seed))
    reads = td_level is not None and METHODS[method].distributional  # PPO's scalar critic has no levels
    hyperparams = dict(settings["hyperparams"], **({"td_level": td_level} if reads else {}))
    model = HuRiPPO("MlpPolicy", env, method=method, seed=seed, device="cpu", **hyperparams)
    start = time.perf_counter()
    model.learn(timesteps or settings["timesteps"])
    train_time = time.perf_counter() - start

    eval_env = VecNormalize(
        make_vec_env(env_id, n_envs=1, seed=10_000 + seed), training=False, norm_reward=False
    )
    eval_env.obs_rms = env.obs_rms
    mean_return, _ = evaluate_policy(model, eval_env, n_eval_episodes=10, deterministic=True)
    return dict(
        env=env_id, method=method, td_level=model.td_level, seed=seed, final_return=float(mean_return),
        train_time_s=train_time,
    )  # fmt: skip


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--envs", nargs="+", default=list(SETTINGS))
    parser.add_argument("--methods", nargs="+", default=["huri-baseline", "huri"])
    parser.add_argument("--seeds", nargs="+", type=int, default=[0, 1, 2])
    parser.add_argument("--timesteps", type=int, default=None, help="override the per-env budget")
    parser.add_argument(
        "--td-level", choices=("state", "step"), default=None,
        help="the TD reading of every method with a quantile critic (default: each method's, 'state')",
    )  # fmt: skip
    parser.add_argument("--output", default=None, help="write the per-run results as JSON lines here")
    args = parser.parse_args()
    th.set_num_threads(1)

    results = []
    for env_id in args.envs:
        for seed in args.seeds:
            for method in args.methods:
                result = run(env_id, method, seed, args.timesteps, args.td_level)
                results.append(result)
                print(json.dumps(result), flush=True)
                if args.output:
                    with open(args.output, "a") as file:
                        file.write(json.dumps(result) + "\n")

    print("\n| env | method | steps | final return, mean ± std over seeds | per seed | train time / run |")
    print("|---|---|---|---|---|---|")
    for env_id in args.envs:
        for method in args.methods:
            runs = [r for r in results if r["env"] == env_id and r["method"] == method]
            returns = [r["final_return"] for r in runs]
            spread = statistics.stdev(returns) if len(returns) > 1 else float("nan")
            steps = args.timesteps or SETTINGS[env_id]["timesteps"]
            per_seed = ", ".join(f"{value:.0f}" for value in returns)
            minutes = np.mean([r["train_time_s"] for r in runs]) / 60
            label = method if args.td_level is None else f"{method} (td_level {args.td_level})"
            print(
                f"| {env_id} | {label} | {steps} | {np.mean(returns):.1f} ± {spread:.1f} | {per_seed} | "
                f"{minutes:.1f} min |"
            )


if __name__ == "__main__":
    main()
