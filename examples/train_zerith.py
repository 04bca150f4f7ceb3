"""Train Zerith-1 to walk with HuRi (or another method) on the batched environment, on a CPU.

    python examples/train_zerith.py                                   # HuRi, the Zerith1-v0 CPU preset
    python examples/train_zerith.py --algo huri-baseline --seed 1     # PPO baseline, same networks
    python examples/train_zerith.py --resume logs/huri/Zerith1-v0_1   # continue a run (model + normalizer)

The hyperparameters are the `Zerith1-v0` preset of `hyperparams/huri.yml`, the one `rl_zoo3 train` reads,
but the robots run in one process (`zerith_gym.make_vec_env`) instead of RL Zoo's one-env-per-robot
VecEnv, which is several times faster on a CPU. The run is written in RL Zoo's layout
(`<log-folder>/<algo>/Zerith1-v0_<id>/Zerith1-v0.zip` with `Zerith1-v0/config.yml`, `args.yml` and
`vecnormalize.pkl`), so RL Zoo's tools read it:

    rl_zoo3 enjoy --algo huri --env Zerith1-v0 -f logs/ --no-render -n 1000
    python examples/watch_zerith.py logs/huri/Zerith1-v0_1

Checkpoints (model and normalizer) are written every `--checkpoint-freq` steps; TensorBoard logs include
the episode sums of every reward term (`terms/<name>`) and the fall rate.
"""

from __future__ import annotations

import argparse
import dataclasses
import time
from pathlib import Path
from typing import Any

import torch as th
import yaml
from stable_baselines3.common.callbacks import CallbackList, CheckpointCallback
from stable_baselines3.common.vec_env import VecEnv, VecNormalize

import zerith_gym
from sb3_huri import HuRiPPO
from sb3_huri.zoo import METHODS, algorithm_kwargs, normalize_kwargs, read_preset
from zerith_gym.callbacks import RewardTermsLogger
from zerith_gym.randomization import NOMINAL, RandomizationRanges
from zerith_gym.scenarios import Scenario, get_scenario

ENV_ID = "Zerith1-v0"
ROOT = Path(__file__).resolve().parent.parent
DEFAULT_PRESET = ROOT / "hyperparams" / "huri.yml"


def next_run_folder(log_folder: Path, algo: str) -> Path:
    """`<log_folder>/<algo>/Zerith1-v0_<id>` with the next free id, as RL Zoo numbers its runs."""
    ids = [int(p.name.rsplit("_", 1)[1]) for p in (log_folder / algo).glob(f"{ENV_ID}_*") if p.is_dir()]
    return log_folder / algo / f"{ENV_ID}_{max(ids, default=0) + 1}"


def save_run(model: HuRiPPO, run: Path, preset: dict[str, Any], args: dict[str, Any]) -> None:
    """Model, normalizer, preset and arguments in RL Zoo's layout (what `rl_zoo3 enjoy` loads)."""
    stats = run / ENV_ID
    stats.mkdir(parents=True, exist_ok=True)
    model.save(run / f"{ENV_ID}.zip")
    env = model.get_env()
    if isinstance(env, VecNormalize):
        env.save(str(stats / "vecnormalize.pkl"))
    with open(stats / "config.yml", "w") as f:
        yaml.safe_dump(preset, f)
    with open(stats / "args.yml", "w") as f:
        yaml.safe_dump(args, f)


def scaled_scenario(scenario: Scenario, scale: float) -> Scenario:
    """`scenario` with its randomization ranges, pushes and external forces shrunk towards none by `scale`.

    Every range (lo, hi) of the randomization moves to (1 - scale) * nominal + scale * (lo, hi), the reset
    tilt and the observation noise are multiplied by `scale`, and so is the external force's magnitude.
    """
    ranges, changes = scenario.randomization, {}
    for field in dataclasses.fields(RandomizationRanges):
        value, nominal = getattr(ranges, field.name), getattr(NOMINAL, field.name)
        if isinstance(value, tuple):
            changes[field.name] = tuple(
                (1 - scale) * n + scale * v for v, n in zip(value, nominal, strict=True)
            )
        elif field.name in ("init_roll_pitch", "observation_noise"):
            changes[field.name] = scale * value
    force = scenario.force
    return dataclasses.replace(
        scenario,
        name=f"{scenario.name}x{scale:g}",
        randomization=dataclasses.replace(ranges, **changes),
        force=dataclasses.replace(force, magnitude=tuple(scale * m for m in force.magnitude)),
    )


def curriculum(budget: int, steps: int, stages: int, start: int = 0) -> list[tuple[float, int]]:
    """(randomization scale, env steps) for the env steps `start` to `start + budget` of a run.

    Over a run's first `steps` env steps the scale rises from 0 to 1 in `stages` equal stages (0, 1/stages,
    ...); after them it is 1. `start` > 0 continues a resumed run where it stopped.
    """
    steps = max(steps, 0)
    bounds = [k * steps // stages for k in range(stages)] + [steps]
    end, plan = start + budget, []
    for k in range(stages):
        low, high = max(bounds[k], start), min(bounds[k + 1], end)
        if high > low:
            plan.append((k / stages, high - low))
    if end > max(steps, start):
        plan.append((1.0, end - max(steps, start)))
    return plan


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument(
        "--algo", default="huri", choices=list(METHODS), help="method (RL Zoo algorithm name)"
    )
    parser.add_argument("-conf", "--conf-file", type=Path, default=DEFAULT_PRESET, help="hyperparameter file")
    parser.add_argument("-n", "--n-timesteps", type=int, default=None, help="override the preset's budget")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("-f", "--log-folder", type=Path, default=Path("logs"))
    parser.add_argument(
        "--resume", type=Path, default=None, help="a run folder to continue (-n more steps; same curriculum)"
    )
    parser.add_argument("--checkpoint-freq", type=int, default=500_000, help="env steps between checkpoints")
    parser.add_argument("--threads", type=int, default=1, help="torch threads (1 is fastest for small nets)")
    parser.add_argument(
        "--workers",
        type=int,
        default=None,
        help="processes stepping the robots (same results for any number; default: one per core, 0: none)",
    )
    parser.add_argument(
        "--physics-threads", type=int, default=1, help="threads stepping the physics of each process's robots"
    )
    parser.add_argument(
        "--curriculum-steps",
        type=int,
        default=0,
        help="grow the randomization from none to the scenario's over this many steps (0: no curriculum)",
    )
    parser.add_argument("--curriculum-stages", type=int, default=8, help="steps of the curriculum")
    parser.add_argument("--tensorboard-log", default=None)
    args = parser.parse_args()
    th.set_num_threads(args.threads)

    preset = read_preset(ENV_ID, args.conf_file)
    budget = args.n_timesteps or int(preset["n_timesteps"])
    env_kwargs = dict(preset.get("env_kwargs") or {})
    scenario = get_scenario(env_kwargs.pop("scenario", "train"))
    norm = normalize_kwargs(preset)
    run = args.resume or next_run_folder(args.log_folder, args.algo)

    def make_env(scale: float, previous: VecNormalize | None) -> VecEnv:
        env = zerith_gym.make_vec_env(
            int(preset["n_envs"]),
            seed=args.seed,
            scenario=scaled_scenario(scenario, scale),
            workers=args.workers,
            physics_threads=args.physics_threads,
            **env_kwargs,
        )
        if norm is None:
            return env
        if previous is None and args.resume:
            return VecNormalize.load(str(run / ENV_ID / "vecnormalize.pkl"), env)
        wrapped = VecNormalize(env, gamma=preset.get("gamma", 0.99), **norm)
        if previous is not None:  # a new stage keeps the statistics learned so far
            wrapped.obs_rms, wrapped.ret_rms = previous.obs_rms, previous.ret_rms
            previous.close()
        return wrapped

    if args.resume:
        model = HuRiPPO.load(run / f"{ENV_ID}.zip", tensorboard_log=args.tensorboard_log)
        start = model.num_timesteps
    else:
        model, start = None, 0
    stages = curriculum(budget, args.curriculum_steps, args.curriculum_stages, start)
    env = make_env(stages[0][0], None)
    if model is None:
        model = HuRiPPO(
            preset["policy"],
            env,
            variant=METHODS[args.algo],
            seed=args.seed,
            tensorboard_log=args.tensorboard_log,
            verbose=1,
            **algorithm_kwargs(preset),
        )
    else:
        model.set_env(env)
    run_args = {
        "algo": args.algo,
        "env": ENV_ID,
        "seed": args.seed,
        "env_kwargs": {**env_kwargs, "scenario": scenario.name},
    }
    print(f"Writing to {run}; curriculum (randomization scale, steps): {stages}")
    checkpoints = CheckpointCallback(
        max(args.checkpoint_freq // env.num_envs, 1), str(run), save_vecnormalize=True
    )
    callbacks = CallbackList([RewardTermsLogger(), checkpoints])
    began = time.time()
    for k, (scale, steps) in enumerate(stages):
        if k > 0:
            env = make_env(scale, model.get_env())
            model.set_env(env)
        model.learn(steps, callback=callbacks, reset_num_timesteps=not args.resume and k == 0)
    save_run(model, run, preset, run_args)
    print(f"{model.num_timesteps} steps in {time.time() - began:.0f} s; saved {run / (ENV_ID + '.zip')}")


if __name__ == "__main__":
    main()
