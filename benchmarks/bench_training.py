"""End-to-end training throughput on Zerith1-v0: env steps/s with updates, HuRiPPO against SB3 PPO.

Each configuration trains for a few iterations (after one warm-up iteration) on the batched env
(`zerith_gym.make_vec_env`, or SB3's `DummyVecEnv` of single envs with `--vec dummy`) wrapped in
`VecNormalize`, with the CPU preset's settings (n_steps 60, 5 epochs, 4 minibatches) and prints the
steps/s of the whole loop and the share of time spent collecting rollouts (env + policy inference)
against updating the networks.

    python benchmarks/bench_training.py                                  # 16 and 32 envs, both networks
    python benchmarks/bench_training.py --num-envs 32 --nets 512,256,128 --iterations 5
    python benchmarks/bench_training.py --num-envs 32 --nets 256,128,64 --physics-threads 1 2

`--physics-threads` (batched env only) steps the robots' physics in that many threads while the policy
waits for them; several values are measured one after another.
"""

from __future__ import annotations

import argparse
import time

import torch
from stable_baselines3 import PPO
from stable_baselines3.common.callbacks import BaseCallback
from stable_baselines3.common.env_util import make_vec_env as sb3_make_vec_env
from stable_baselines3.common.vec_env import VecEnv, VecNormalize
from torch import nn

import zerith_gym
from sb3_huri import HuRiPPO

N_STEPS = 60
N_EPOCHS = 5
N_MINIBATCHES = 4


class RolloutTimer(BaseCallback):
    """Wall time spent collecting rollouts (from rollout start to rollout end), summed."""

    def __init__(self) -> None:
        super().__init__()
        self.collecting = 0.0
        self._start = 0.0

    def _on_rollout_start(self) -> None:
        self._start = time.perf_counter()

    def _on_rollout_end(self) -> None:
        self.collecting += time.perf_counter() - self._start

    def _on_step(self) -> bool:
        return True


def make_env(kind: str, num_envs: int, seed: int, physics_threads: int = 1) -> VecEnv:
    if kind == "batched":
        env = zerith_gym.make_vec_env(num_envs, seed=seed, physics_threads=physics_threads)
    else:
        env = sb3_make_vec_env("Zerith1-v0", n_envs=num_envs, seed=seed)
    return VecNormalize(env, norm_obs=True, norm_reward=True)


def build(algo: str, env: VecEnv, net: list[int], seed: int):
    num_envs = env.num_envs
    policy_kwargs = dict(net_arch=net, activation_fn=nn.ELU, log_std_init=-2.0)
    common = dict(n_steps=N_STEPS, n_epochs=N_EPOCHS, seed=seed, policy_kwargs=policy_kwargs, device="cpu")
    if algo == "ppo":
        return PPO("MultiInputPolicy", env, batch_size=num_envs * N_STEPS // N_MINIBATCHES, **common)
    return HuRiPPO("MlpPolicy", env, variant=algo, n_minibatches=N_MINIBATCHES, **common)


def measure(
    algo: str, kind: str, num_envs: int, net: list[int], iterations: int, seed: int, physics_threads: int
) -> tuple:
    env = make_env(kind, num_envs, seed, physics_threads)
    model = build(algo, env, net, seed)
    per_iteration = num_envs * N_STEPS
    model.learn(per_iteration)  # warm-up: allocations, first resets
    timer = RolloutTimer()
    start = time.perf_counter()
    model.learn(iterations * per_iteration, callback=timer, reset_num_timesteps=False)
    elapsed = time.perf_counter() - start
    env.close()
    return iterations * per_iteration / elapsed, timer.collecting / elapsed


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--num-envs", type=int, nargs="*", default=[16, 32])
    parser.add_argument("--nets", nargs="*", default=["512,256,128", "256,128,64"])
    parser.add_argument("--algos", nargs="*", default=["ppo", "huri"], help="ppo or HuRiPPO variants")
    parser.add_argument("--vec", choices=["batched", "dummy"], default="batched")
    parser.add_argument("--iterations", type=int, default=3)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--threads", type=int, default=1, help="torch threads")
    parser.add_argument("--physics-threads", type=int, nargs="*", default=[1], help="env physics threads")
    args = parser.parse_args()
    torch.set_num_threads(args.threads)
    print(f"torch {torch.__version__}, {torch.get_num_threads()} threads; env: {args.vec}; n_steps {N_STEPS}")
    print("algo                       envs  net          physics threads  steps/s  collecting")
    for num_envs in args.num_envs:
        for net_text in args.nets:
            net = [int(width) for width in net_text.split(",")]
            for algo in args.algos:
                for physics_threads in args.physics_threads:
                    rate, collecting = measure(
                        algo, args.vec, num_envs, net, args.iterations, args.seed, physics_threads
                    )
                    name = "SB3 PPO" if algo == "ppo" else f"HuRiPPO variant={algo}"
                    print(
                        f"{name:26s} {num_envs:4d}  {net_text:13s} {physics_threads:15d} "
                        f"{rate:8.0f}  {collecting:9.0%}"
                    )


if __name__ == "__main__":
    main()
