"""End-to-end training throughput on Zerith1-v0: HuRiPPO and SB3 PPO against raw physics, in one run.

Each configuration trains with the `Zerith1-v0` preset of `hyperparams/huri.yml` (rollout length, epochs,
minibatches, networks, VecNormalize, reward weights; `--num-envs` and `--nets` override the preset's
robots and networks) on `zerith_gym.make_vec_env` with its defaults (worker processes picked from the
machine), or on SB3's `DummyVecEnv` of single envs with `--vec dummy`, and prints

- env steps/s of the whole loop (collection and updates) over a few iterations after a warm-up one,
- the share of that time spent collecting rollouts (env steps and policy inference),
- the ratio to raw physics on all cores: `mj_step(nstep=4)` of the same robots (the env's own randomized
  models) in as many threads as cores, measured between the training runs of the same configuration,
- HuRiPPO's wall time per env step relative to SB3 PPO's (same env, same networks, same callbacks).

Both algorithms run with the preset's callbacks (RL Zoo reads them the same way), among them
`UpdateThreads`: torch on one thread while collecting, on every core while updating.

    python benchmarks/bench_training.py                                   # the preset: 32 robots
    python benchmarks/bench_training.py --num-envs 32 64 --iterations 5
    python benchmarks/bench_training.py --workers 0 --physics-threads 1 2   # in-process env, for reference
    python benchmarks/bench_training.py --num-envs 256 1024 --threads 4     # a 16-core machine
    python benchmarks/bench_training.py --num-envs 1024 --device cuda       # its networks on a GPU
    python benchmarks/bench_training.py --conf-file hyperparams/huri_robust.yml --num-envs 32 256 \
        --samples-per-update 16384 --workers 0 --algos huri-baseline huri   # one core, same update size

`--threads` sets torch's threads at the start (default 1; the preset's `UpdateThreads` then switches
them by phase). The machine's other load changes absolute rates; the ratios are what to compare.
"""

from __future__ import annotations

import argparse
import time

import numpy as np
import torch
from bench_env import physics_rate, random_actions
from rl_zoo3.utils import get_callback_list
from stable_baselines3 import PPO
from stable_baselines3.common.callbacks import BaseCallback
from stable_baselines3.common.env_util import make_vec_env as sb3_make_vec_env
from stable_baselines3.common.vec_env import VecEnv, VecNormalize

import zerith_gym
from sb3_huri import HuRiPPO
from sb3_huri.zoo import algorithm_kwargs, normalize_kwargs, read_preset
from zerith_gym.cpu.workers import available_cores

ENV_ID = "Zerith1-v0"


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


def make_env(preset: dict, kind: str, num_envs: int, seed: int, env_options: dict) -> VecEnv:
    env_kwargs = dict(preset.get("env_kwargs") or {})
    if kind == "batched":
        env = zerith_gym.make_vec_env(num_envs, seed=seed, **env_kwargs, **env_options)
    else:
        env = sb3_make_vec_env(ENV_ID, n_envs=num_envs, seed=seed, env_kwargs=env_kwargs)
    return VecNormalize(env, gamma=preset.get("gamma", 0.99), **(normalize_kwargs(preset) or {}))


def build(algo: str, preset: dict, env: VecEnv, net: list[int] | None, seed: int, device: str = "cpu"):
    kwargs = algorithm_kwargs(preset)
    if net is not None:
        kwargs["policy_kwargs"] = dict(kwargs.get("policy_kwargs") or {}, net_arch=net)
    if algo == "ppo":  # SB3's PPO: the same settings, its minibatch size from the preset's minibatch count
        n_minibatches = kwargs.pop("n_minibatches")
        kwargs["batch_size"] = env.num_envs * kwargs["n_steps"] // n_minibatches
        for name in ("n_quantiles", "sr_lambda", "expectation_coef", "quantile_coef"):
            kwargs.pop(name, None)
        return PPO("MultiInputPolicy", env, seed=seed, device=device, **kwargs)
    return HuRiPPO("MultiInputPolicy", env, method=algo, seed=seed, device=device, **kwargs)


def train_rate(
    algo: str,
    preset: dict,
    env: VecEnv,
    net: list[int] | None,
    iterations: int,
    seed: int,
    callbacks: bool,
    device: str = "cpu",
):
    """Env steps/s with updates over `iterations` iterations after a warm-up one, and the collecting share."""
    model = build(algo, preset, env, net, seed, device)
    per_iteration = env.num_envs * model.n_steps
    callbacks = get_callback_list(preset) if callbacks else []  # reward-term logs, curriculum, threads
    model.learn(per_iteration, callback=callbacks)  # warm-up: allocations, first resets
    timer = RolloutTimer()
    start = time.perf_counter()
    model.learn(iterations * per_iteration, callback=[timer, *callbacks], reset_num_timesteps=False)
    elapsed = time.perf_counter() - start
    return iterations * per_iteration / elapsed, timer.collecting / elapsed


def raw_rate(num_envs: int, seed: int, threads: int, env_kwargs: dict) -> float:
    """Robot-steps/s of raw physics of `num_envs` robots (the env's own models) on `threads` threads."""
    env = zerith_gym.make_vec_env(num_envs, seed=seed, workers=0, **env_kwargs)
    env.reset()
    rate = physics_rate(env.robots.sim, random_actions(max(20_000 // num_envs, 40), num_envs, 0.3), threads)
    env.close()
    return rate


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--num-envs", type=int, nargs="*", default=None, help="default: the preset's")
    parser.add_argument("--nets", nargs="*", default=[None], help="e.g. 512,256,128 (default: the preset's)")
    parser.add_argument("--algos", nargs="*", default=["ppo", "huri"], help="ppo (SB3 PPO) or methods")
    parser.add_argument("--vec", choices=["batched", "dummy"], default="batched")
    parser.add_argument("--workers", type=int, nargs="*", default=[None], help="env workers (default: auto)")
    parser.add_argument("--physics-threads", type=int, nargs="*", default=[1], help="env physics threads")
    parser.add_argument("--iterations", type=int, default=4)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--threads", type=int, default=1, help="torch threads at the start")
    parser.add_argument("--no-callbacks", action="store_true", help="without the preset's callbacks")
    parser.add_argument("--conf-file", default=None, help="hyperparameter file (default: the packaged one)")
    parser.add_argument("--device", default="cpu", help="torch device of the networks (cpu, cuda)")
    parser.add_argument(
        "--samples-per-update",
        type=int,
        default=None,
        help="n_steps = this / robots: every --num-envs updates on as many samples (default: the preset's)",
    )
    args = parser.parse_args()
    torch.set_num_threads(args.threads)
    preset = read_preset(ENV_ID, args.conf_file)
    cores = available_cores()
    env_kwargs = dict(preset.get("env_kwargs") or {})
    print(
        f"torch {torch.__version__}, {torch.get_num_threads()} threads; {cores} cores; env: {args.vec}; "
        f"preset n_steps {preset['n_steps']}, n_epochs {preset['n_epochs']}"
    )
    print(
        "algo                  envs  net          workers  phys.thr  steps/s  collecting  "
        f"raw physics ({cores} thr)  ratio  vs PPO"
    )
    for num_envs in args.num_envs or [int(preset["n_envs"])]:
        if args.samples_per_update:
            preset = dict(preset, n_steps=args.samples_per_update // num_envs)
        for net_text in args.nets:
            net = None if net_text is None else [int(width) for width in net_text.split(",")]
            for workers in args.workers:
                for physics_threads in args.physics_threads:
                    options = dict(workers=workers, physics_threads=physics_threads)
                    ppo_rate = None
                    for algo in args.algos:
                        raw_before = raw_rate(num_envs, args.seed, cores, env_kwargs)
                        env = make_env(preset, args.vec, num_envs, args.seed, options)
                        used_workers = getattr(env.venv, "workers", "-")
                        rate, collecting = train_rate(
                            algo, preset, env, net, args.iterations, args.seed, not args.no_callbacks,
                            args.device,
                        )  # fmt: skip
                        env.close()
                        raw = float(np.mean([raw_before, raw_rate(num_envs, args.seed, cores, env_kwargs)]))
                        if algo == "ppo":
                            ppo_rate = rate
                        versus = f"{ppo_rate / rate:6.2f}" if ppo_rate and algo != "ppo" else "     -"
                        name = "SB3 PPO" if algo == "ppo" else f"HuRiPPO {algo}"
                        print(
                            f"{name:20s} {num_envs:5d}  {net_text or 'preset':12s} {used_workers!s:>7s} "
                            f"{physics_threads:9d} {rate:8.0f}  {collecting:9.0%}  {raw:20.0f}  "
                            f"{rate / raw:5.3f}  {versus}",
                            flush=True,
                        )


if __name__ == "__main__":
    main()
