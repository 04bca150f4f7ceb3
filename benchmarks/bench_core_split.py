"""Two trainings of one core each, or one training of every core: which trains more samples per second here.

A campaign of many runs can give each run the whole machine (its robots in a slice per core, the update on
every core) or split the cores, one run per core (every robot in the run's own process, the update on one
thread). This times both on the same preset and method, side by side in one command:

- `one run, all cores`: one training process with the machine's cores (the env's default worker processes;
  the preset's `UpdateThreads` uses every core for the update);
- `N runs, one core each`: as many training processes as cores, started together, each pinned to its own
  core (`os.sched_setaffinity`, so the env and torch see one core: no worker process, one thread).

Each process trains `--steps` env steps from scratch with the preset's callbacks and reports its env steps
per second over the `learn()` call (start-up excluded). The figure to compare is the machine's total:
steps/s of the one run against the sum over the split runs.

    python benchmarks/bench_core_split.py                                  # the robust recipe, HuRi
    python benchmarks/bench_core_split.py --algo huri-baseline --steps 500000
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
ENV_ID = "Zerith1-v0"


def train_and_time(conf: Path, algo: str, steps: int, seed: int) -> dict[str, float]:
    """Train `steps` env steps of the preset in this process; its steps/s over `learn()`."""
    import torch as th
    from rl_zoo3.utils import get_callback_list
    from stable_baselines3.common.callbacks import CallbackList

    from sb3_huri.runner.build import preset_env, preset_model
    from sb3_huri.zoo import read_preset

    th.set_num_threads(1)
    preset = read_preset(ENV_ID, conf)
    env = preset_env(preset, seed=seed)
    try:
        model = preset_model(preset, env, method=algo, seed=seed, device="cpu")
        began = time.perf_counter()
        model.learn(steps, callback=CallbackList(get_callback_list(preset)))
        seconds = time.perf_counter() - began
    finally:
        env.close()
    return {"steps": model.num_timesteps, "seconds": seconds, "steps_per_s": model.num_timesteps / seconds}


def child_command(args: argparse.Namespace, seed: int) -> list[str]:
    """This script, run as one timed training that prints its figures as JSON."""
    return [
        sys.executable, __file__, "--child", "--conf", str(args.conf), "--algo", args.algo,
        "--steps", str(args.steps), "--seed", str(seed),
    ]  # fmt: skip


def run_children(args: argparse.Namespace, cores: list[int | None]) -> list[dict[str, float]]:
    """One child per entry of `cores`, started together; a core pins its child to it, None leaves it free."""
    children = []
    for i, core in enumerate(cores):
        pin = None if core is None else (lambda core=core: os.sched_setaffinity(0, {core}))
        children.append(
            subprocess.Popen(child_command(args, i), stdout=subprocess.PIPE, text=True, preexec_fn=pin)
        )
    results = []
    for child in children:
        out, _ = child.communicate()
        if child.returncode != 0:
            raise SystemExit(f"a timed training failed (exit {child.returncode})")
        results.append(json.loads(out.strip().splitlines()[-1]))
    return results


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--conf", type=Path, default=ROOT / "hyperparams" / "huri_robust.yml")
    parser.add_argument("--algo", default="huri", help="method (RL Zoo algorithm name)")
    parser.add_argument("--steps", type=int, default=1_000_000, help="env steps per training")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--child", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child:
        print(json.dumps(train_and_time(args.conf, args.algo, args.steps, args.seed)))
        return
    cores = sorted(os.sched_getaffinity(0))
    whole = run_children(args, [None])[0]
    split = run_children(args, cores)
    total = sum(r["steps_per_s"] for r in split)
    print(f"{args.algo}, {args.conf.name}, {args.steps} steps per training, {len(cores)} cores")
    print(f"one run, all cores:        {whole['steps_per_s']:8.0f} steps/s")
    each = ", ".join(f"{r['steps_per_s']:.0f}" for r in split)
    print(f"{len(cores)} runs, one core each:  {total:8.0f} steps/s in all ({each})")
    print(f"split / whole: {total / whole['steps_per_s']:.2f}")


if __name__ == "__main__":
    main()
