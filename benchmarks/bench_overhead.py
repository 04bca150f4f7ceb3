"""HuRiPPO's overhead over SB3's PPO, side by side in one run: wall and CPU time of the same training.

Two cases, each trained by SB3's ``PPO`` and by HuRiPPO's methods with the same env, seed, rollout, update
sizes and networks, in turns (PPO, then each method, repeated) so that the machine's other load falls on
all of them alike. The medians over repeats and their ratios to PPO are printed as a markdown table.

- ``walker``: Gymnasium's ``Walker2d-v5``, one env in ``VecNormalize``, SB3's PPO defaults (2,048 steps per
  rollout, minibatches of 64, 10 epochs, [64, 64] tanh networks), written out for both so that a checkout
  from before HuRiPPO took PPO's defaults measures the same thing. PPO is ``PPO("MlpPolicy", env)``.
- ``robust32``: ``Zerith1-v0`` with the robust recipe (``hyperparams/huri_robust.yml``) on its 32 robots,
  in this process (``workers=0``): 512 steps per rollout, 4 minibatches of 4,096, 5 epochs, the recipe's
  networks. PPO is SB3's with a scalar ``HuRiPolicy`` (which reads the recipe's ``Dict`` observation:
  the actor the ``"policy"`` entry, the critic all). The recipe's KL-adaptive rate and critic rate are
  left out for every algorithm: they are not PPO's, and what is measured is the critic and risk parts.

``--profile`` adds, per algorithm, the seconds cProfile gives to each part of a training (one more run,
not timed): the env, the policy's rollout inference, HuRi's end-of-rollout assessment, the update's
forward and backward passes, the optimizer, the critic loss and the RND predictor's training.

    python benchmarks/bench_overhead.py                                   # both cases, 3 repeats
    python benchmarks/bench_overhead.py --cases walker --repeats 5 --profile
"""

from __future__ import annotations

import argparse
import cProfile
import pstats
import statistics
import time
import warnings
from collections.abc import Callable
from pathlib import Path
from typing import Any

import torch as th
from stable_baselines3 import PPO
from stable_baselines3.common.env_util import make_vec_env
from stable_baselines3.common.vec_env import VecNormalize
from torch import nn

from sb3_huri import HuRiPolicy, HuRiPPO, UnnormalizedRewardWarning

ROOT = Path(__file__).resolve().parent.parent
PPO_DEFAULTS = dict(
    n_steps=2048,
    batch_size=64,
    n_epochs=10,
    learning_rate=3e-4,
    ent_coef=0.0,
    vf_coef=0.5,
    max_grad_norm=0.5,
    policy_kwargs=dict(net_arch=dict(pi=[64, 64], vf=[64, 64]), activation_fn=nn.Tanh),
)
"""SB3's PPO defaults for what HuRiPPO shares with it (HuRiPPO's own defaults since it took them)."""
NOT_PPO = ("desired_kl", "critic_learning_rate")
"""Arguments of the robust recipe that SB3's PPO has no counterpart of: left out for every algorithm."""
HURI_ONLY = ("n_quantiles", "sr_lambda", "expectation_coef", "quantile_coef", "n_minibatches")
"""The recipe's arguments of HuRi's own (and its minibatch count, given to PPO as a size)."""

PARTS: dict[str, tuple[tuple[str, str], ...]] = {
    "whole training": (("stable_baselines3/common/on_policy_algorithm.py", "learn"),),
    "env steps": (("stable_baselines3/common/vec_env/base_vec_env.py", "step"),),
    "rollout inference": (("stable_baselines3/common/policies.py", "forward"),),
    "end of rollout (risk, advantages)": (
        ("sb3_huri/huri/huri.py", "_finish_rollout"),
        ("stable_baselines3/common/buffers.py", "compute_returns_and_advantage"),
    ),
    "update forward": (("stable_baselines3/common/policies.py", "evaluate_actions"),),
    "critic loss": (("sb3_huri/huri/huri.py", "_critic_loss"), ("torch/nn/functional.py", "mse_loss")),
    "backward passes": (("torch/_tensor.py", "backward"),),
    "Adam steps": (("torch/optim/adam.py", "step"),),
    "RND predictor fit": (("sb3_huri/common/rnd.py", "fit"),),
}
"""The parts of a training that --profile reports, each the largest cumulative time of its functions (a
path's ending, a name): the outermost of nested calls, e.g. VecNormalize's step around its env's."""


def walker(algo: str, seed: int) -> tuple[Any, Callable[[], None]]:
    """The ``walker`` case: a model of `algo` and the function that closes its env."""
    env = VecNormalize(make_vec_env("Walker2d-v5", n_envs=1, seed=seed))
    kwargs = dict(PPO_DEFAULTS, seed=seed, device="cpu")
    if algo == "ppo":
        return PPO("MlpPolicy", env, **kwargs), env.close
    return HuRiPPO("MlpPolicy", env, method=algo, **kwargs), env.close


def robust32(algo: str, seed: int) -> tuple[Any, Callable[[], None]]:
    """The ``robust32`` case: a model of `algo` on the robust recipe's 32 robots, and its env's close."""
    from sb3_huri.runner.build import preset_env
    from sb3_huri.zoo import algorithm_kwargs, read_preset

    preset = read_preset("Zerith1-v0", ROOT / "hyperparams" / "huri_robust.yml")
    env = preset_env(preset, seed=seed, workers=0)
    kwargs = {k: v for k, v in algorithm_kwargs(preset).items() if k not in NOT_PPO}
    kwargs.update(seed=seed, device="cpu")
    if algo != "ppo":
        return HuRiPPO(preset["policy"], env, method=algo, **kwargs), env.close
    batch_size = preset["n_steps"] * preset["n_envs"] // preset["n_minibatches"]
    shared = {k: v for k, v in kwargs.items() if k not in HURI_ONLY}
    shared["policy_kwargs"] = dict(shared.get("policy_kwargs") or {}, n_quantiles=1)
    return PPO(HuRiPolicy, env, batch_size=batch_size, **shared), env.close


CASES = {"walker": (walker, 8192), "robust32": (robust32, 32768)}
"""Each case: its model maker and the steps a timed training takes (4 rollouts, and 2)."""


def timed_learn(case: str, algo: str, seed: int, steps: int) -> tuple[float, float]:
    """Wall and CPU seconds of this process for ``learn(steps)`` of a new model."""
    model, close = CASES[case][0](algo, seed)
    start, start_cpu = time.perf_counter(), time.process_time()
    model.learn(steps)
    elapsed, elapsed_cpu = time.perf_counter() - start, time.process_time() - start_cpu
    close()
    return elapsed, elapsed_cpu


def profiled_parts(case: str, algo: str, steps: int) -> dict[str, float]:
    """Cumulative seconds of each of ``PARTS`` in a profiled ``learn(steps)``."""
    model, close = CASES[case][0](algo, 0)
    profile = cProfile.Profile()
    profile.runcall(model.learn, steps)
    close()
    stats = pstats.Stats(profile).stats  # type: ignore[attr-defined]
    return {
        part: max(
            (cumulative for (path, _, name), (*_, cumulative, _) in stats.items()
             if any(path.endswith(ending) and name == function for ending, function in functions)),
            default=0.0,
        )
        for part, functions in PARTS.items()
    }  # fmt: skip


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--cases", nargs="+", choices=list(CASES), default=list(CASES))
    parser.add_argument("--methods", nargs="+", default=["huri-baseline", "huri-neutral", "huri"])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--profile", action="store_true", help="also the seconds of each part of a training")
    args = parser.parse_args()
    th.set_num_threads(1)
    warnings.simplefilter("ignore", UnnormalizedRewardWarning)  # timing: the walker's rewards are raw

    print(f"torch threads=1 repeats={args.repeats}")
    print("| case | algorithm | steps/s | wall time (s) | to PPO | CPU time (s) | to PPO |")
    print("|---|---|---|---|---|---|---|")
    algos = ["ppo", *args.methods]
    for case in args.cases:
        steps = CASES[case][1]
        times: dict[str, list[tuple[float, float]]] = {algo: [] for algo in algos}
        for repeat in range(args.repeats):
            for algo in algos:
                times[algo].append(timed_learn(case, algo, repeat, steps))
        wall = {algo: statistics.median(w for w, _ in runs) for algo, runs in times.items()}
        cpu = {algo: statistics.median(c for _, c in runs) for algo, runs in times.items()}
        for algo in algos:
            name = "SB3 PPO" if algo == "ppo" else f"HuRiPPO {algo}"
            print(
                f"| {case} | {name} | {steps / wall[algo]:,.0f} | {wall[algo]:.2f} | "
                f"{wall[algo] / wall['ppo']:.2f}x | {cpu[algo]:.2f} | {cpu[algo] / cpu['ppo']:.2f}x |",
                flush=True,
            )
    if args.profile:
        for case in args.cases:
            parts = {algo: profiled_parts(case, algo, CASES[case][1]) for algo in algos}
            print(f"\n{case}, seconds under cProfile (one run each):\n")
            print("| part | " + " | ".join(algos) + " |")
            print("|---|" + "---|" * len(algos))
            for part in PARTS:
                print(f"| {part} | " + " | ".join(f"{parts[algo][part]:.2f}" for algo in algos) + " |")


if __name__ == "__main__":
    main()
