"""Wall-time overhead of HuRiPPO over SB3's PPO: same env, networks, rollout and update sizes, side by side.

Both algorithms use the paper's asymmetric [512, 256, 128] networks (PPO through ``HuRiPolicy`` with a
scalar critic), the same ``n_steps``, ``n_envs``, minibatch size and epochs. Runs alternate between the
algorithms so that machine load affects both alike; the ratios of median wall times and of median CPU
times of this process (less sensitive to other processes on a shared machine) are reported.

    python benchmarks/bench_overhead.py                       # Pendulum-v1, and Zerith1-v0 if installed
    python benchmarks/bench_overhead.py --envs Pendulum-v1 --timesteps 8192 --repeats 3
"""

import argparse
import statistics
import time
import warnings

import gymnasium as gym
import torch as th
from stable_baselines3 import PPO
from stable_baselines3.common.env_util import make_vec_env

from sb3_huri import HuRiPolicy, HuRiPPO, UnnormalizedRewardWarning

# Timing only: both algorithms learn on raw rewards on purpose.
warnings.simplefilter("ignore", UnnormalizedRewardWarning)


def _make_env(env_id: str, n_envs: int, seed: int):
    if env_id.startswith("Zerith"):
        import zerith_gym  # noqa: F401  (registers Zerith1-v0)
    return make_vec_env(env_id, n_envs=n_envs, seed=seed)


def _time_learn(algo: str, env_id: str, args: argparse.Namespace, seed: int) -> tuple[float, float]:
    env = _make_env(env_id, args.n_envs, seed)
    common = dict(
        n_steps=args.n_steps, batch_size=args.batch_size, n_epochs=args.n_epochs, seed=seed, device="cpu"
    )
    if algo == "ppo":
        model = PPO(HuRiPolicy, env, policy_kwargs=dict(n_quantiles=1), ent_coef=0.01, vf_coef=1.0, **common)
    else:
        model = HuRiPPO("MlpPolicy", env, method=algo, **common)
    start, start_cpu = time.perf_counter(), time.process_time()
    model.learn(args.timesteps)
    elapsed, elapsed_cpu = time.perf_counter() - start, time.process_time() - start_cpu
    env.close()
    return elapsed, elapsed_cpu


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--envs", nargs="+", default=["Pendulum-v1", "Zerith1-v0"])
    parser.add_argument("--methods", nargs="+", default=["huri", "huri-baseline"])
    parser.add_argument("--timesteps", type=int, default=16384)
    parser.add_argument("--n-envs", type=int, default=8)
    parser.add_argument("--n-steps", type=int, default=256)
    parser.add_argument("--batch-size", type=int, default=512)
    parser.add_argument("--n-epochs", type=int, default=8)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--threads", type=int, default=1, help="torch intra-op threads")
    args = parser.parse_args()
    th.set_num_threads(args.threads)

    print(
        f"torch threads={args.threads} n_envs={args.n_envs} n_steps={args.n_steps} batch={args.batch_size} "
        f"epochs={args.n_epochs} timesteps={args.timesteps} repeats={args.repeats}"
    )
    print(
        "| env | algorithm | wall time (s) | wall-time ratio to PPO | CPU time (s) | CPU-time ratio to PPO |"
    )
    print("|---|---|---|---|---|---|")
    for env_id in args.envs:
        try:
            _make_env(env_id, 1, 0).close()
        except (gym.error.Error, ImportError) as error:
            print(f"| {env_id} | skipped: {error} | | | | |")
            continue
        algos = ["ppo", *args.methods]
        times: dict[str, list[tuple[float, float]]] = {algo: [] for algo in algos}
        for repeat in range(args.repeats):
            for algo in algos:
                times[algo].append(_time_learn(algo, env_id, args, seed=repeat))
        wall_ppo = statistics.median(wall for wall, _ in times["ppo"])
        cpu_ppo = statistics.median(cpu for _, cpu in times["ppo"])
        for algo in algos:
            wall = statistics.median(wall for wall, _ in times[algo])
            cpu = statistics.median(cpu for _, cpu in times[algo])
            name = "SB3 PPO + HuRiPolicy(n_quantiles=1)" if algo == "ppo" else f"HuRiPPO method={algo}"
            ratios = f"{wall:.2f} | {wall / wall_ppo:.2f}x | {cpu:.2f} | {cpu / cpu_ppo:.2f}x"
            print(f"| {env_id} | {name} | {ratios} |", flush=True)


if __name__ == "__main__":
    main()
