"""KL control late in a Zerith1-v0 run: continue a trained HuRi agent with and without a KL-adaptive rate.

Late in the preset's runs (3-4M steps) PPO's approximate KL reaches 0.1-0.3 per update at the preset's fixed
learning rate. This continues a saved run (by default the shipped HuRi agent, 3M steps) from the same state,
in the training scenario at the randomization scale it had reached, once per arm: the preset as it is, and
``desired_kl`` (the learning rate divided or multiplied by 1.5 per minibatch to keep the KL near it). Each arm
reports the approximate KL per update, the final learning rate and the episode return. The saved run is
only read.

    python benchmarks/bench_kl_control.py --steps 400000 --desired-kl 0.01 0.02

The run keeps its own loss settings (``--expectation-loss``, RND error unnormalized for a model saved
before the normalized one existed), so that only the KL control differs from how it was trained.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np
import torch as th
import yaml
from stable_baselines3.common.vec_env import VecNormalize

import zerith_gym
from sb3_huri import HuRiPPO
from sb3_huri.runner.curve import UpdateRecorder
from zerith_gym.core.scenarios import get_scenario, scaled_scenario

REPO = Path(__file__).resolve().parents[1]
ENV_ID = "Zerith1-v0"


def continue_run(
    run: Path, desired_kl: float | None, steps: int, scale: float, expectation_loss: str, seed: int
) -> dict:
    """Continue the run for ``steps`` steps with the given KL control; the run folder is not written."""
    model = HuRiPPO.load(run / f"{ENV_ID}.zip", device="cpu", seed=seed)
    args_file = run / ENV_ID / "args.yml"
    env_kwargs = (
        dict(yaml.safe_load(args_file.read_text()).get("env_kwargs") or {}) if args_file.is_file() else {}
    )
    scenario = scaled_scenario(get_scenario(env_kwargs.pop("scenario", "train")), scale)
    env = zerith_gym.make_vec_env(model.n_envs, seed=seed, scenario=scenario, **env_kwargs)
    env = VecNormalize.load(str(run / ENV_ID / "vecnormalize.pkl"), env)
    model.set_env(env)
    model.expectation_loss = expectation_loss
    if model.policy.rnd is not None and "target_mean" not in model.policy.rnd.get_extra_state():
        model.policy.rnd.normalize_error = False
    model.desired_kl = desired_kl
    model.kl_learning_rate = None  # the first update starts from the run's learning rate
    stats = UpdateRecorder()
    began = time.time()
    model.learn(steps, callback=stats, reset_num_timesteps=False)
    kls = np.array([row["approx_kl"] for row in stats.rows])
    returns = [row["ep_return"] for row in stats.rows]
    return {
        "desired_kl": desired_kl,
        "steps": steps,
        "wall_s": round(time.time() - began, 1),
        "updates": len(kls),
        "approx_kl_mean": float(kls.mean()),
        "approx_kl_median": float(np.median(kls)),
        "approx_kl_p90": float(np.quantile(kls, 0.9)),
        "share_kl_above_0.05": float((kls > 0.05).mean()),
        "final_learning_rate": stats.rows[-1]["learning_rate"],
        "ep_rew_mean_first": returns[0],
        "ep_rew_mean_last": returns[-1],
        "rows": stats.rows,
    }


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--run", type=Path, default=REPO / "trained_agents" / "huri" / f"{ENV_ID}_1")
    parser.add_argument("--steps", type=int, default=400_000)
    parser.add_argument("--desired-kl", type=float, nargs="*", default=[0.01])
    parser.add_argument("--scale", type=float, default=0.375, help="curriculum scale the run had reached")
    parser.add_argument("--expectation-loss", default="distorted", help="the reading the run trained with")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--arm", type=float, default=None, help="run only this desired KL (0: no KL control)")
    parser.add_argument("--output", type=Path, default=None, help="append JSON lines here")
    args = parser.parse_args()
    th.set_num_threads(1)
    arms = [None, *args.desired_kl] if args.arm is None else [args.arm or None]
    for desired_kl in arms:
        result = continue_run(args.run, desired_kl, args.steps, args.scale, args.expectation_loss, args.seed)
        summary = {key: value for key, value in result.items() if key != "rows"}
        print(json.dumps(summary), flush=True)
        if args.output:
            with args.output.open("a") as file:
                file.write(json.dumps(result) + "\n")


if __name__ == "__main__":
    main()
