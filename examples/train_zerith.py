"""Train Zerith-1 to walk with HuRi (or another method) on the batched environment, on a CPU.

    python examples/train_zerith.py                                   # HuRi, the Zerith1-v0 CPU preset
    python examples/train_zerith.py --algo huri-baseline --seed 1     # PPO baseline, same networks
    python examples/train_zerith.py --resume logs/huri/Zerith1-v0_1   # continue a run where it stopped
    python examples/train_zerith.py --resume logs/huri/Zerith1-v0_1 -params mirror_coef:4.0  # ... + symmetry
    python examples/train_zerith.py -conf hyperparams/huri_robust.yml -f runs --max-wall-minutes 150

It trains what `rl_zoo3 train --algo <algo> --env Zerith1-v0` trains: the `Zerith1-v0` preset of
`hyperparams/huri.yml` on the batched env (`zerith_gym.make_vec_env`: a slice of robots per core),
with the preset's `callback:` entries read as RL Zoo reads them: the reward-term logs
(`zerith_gym.callbacks.RewardTermsLogger`) and the randomization curriculum
(`zerith_gym.callbacks.RandomizationCurriculum`, which grows the randomization from none to the full
training ranges; `--curriculum-steps N` replaces it), or on terrains (`-conf hyperparams/huri_terrain.yml`)
the terrain curriculum (`zerith_gym.callbacks.TerrainCurriculum`). It adds resuming and periodic
checkpoints. The run is
written in RL Zoo's layout (`<log-folder>/<algo>/Zerith1-v0_<id>/Zerith1-v0.zip` with
`Zerith1-v0/config.yml`, `args.yml` and `vecnormalize.pkl`), so RL Zoo's tools read it:

    rl_zoo3 enjoy --algo huri --env Zerith1-v0 -f logs/ --no-render -n 1000
    python examples/watch_zerith.py logs/huri/Zerith1-v0_1

Every `--checkpoint-freq` steps and at the end, the run folder gets its newest checkpoint: model,
normalizer, random states, curriculum stage, terrain levels and the sessions' wall time
(`sb3_huri.zoo.checkpoints`), and `curve.csv` a row per rollout; `<run>/checkpoints/` keeps every
checkpoint's model and normalizer.
`--resume` continues from the newest checkpoint, so a run can train over many sessions (`kill` or Ctrl-C
stops it at the next step with a checkpoint; a hard stop loses at most `--checkpoint-freq` steps).
TensorBoard logs include the episode sums of every reward term (`terms/<name>`) and the fall rate.
"""

from __future__ import annotations

import argparse
import signal
import time
from pathlib import Path
from typing import Any

import torch as th
import yaml
from rl_zoo3.utils import get_callback_list
from stable_baselines3.common.callbacks import CallbackList, CheckpointCallback

from sb3_huri import HuRiPPO
from sb3_huri.zoo import METHODS, next_run_folder, read_preset
from sb3_huri.zoo.checkpoints import RunCheckpoint, RunState, restore_random_states, start_on_levels
from sb3_huri.zoo.presets import preset_env, preset_model, resume_overrides
from zerith_gym.callbacks import RandomizationCurriculum
from zerith_gym.scenarios import get_scenario

ENV_ID = "Zerith1-v0"
ROOT = Path(__file__).resolve().parent.parent
DEFAULT_PRESET = ROOT / "hyperparams" / "huri.yml"


def parse_hyperparams(pairs: list[str]) -> dict[str, Any]:
    """`KEY:VALUE` strings as a dict, each VALUE read as YAML; ValueError for a pair without a colon."""
    parsed = {}
    for pair in pairs:
        key, colon, value = pair.partition(":")
        if not colon or not key:
            raise ValueError(f"-params takes KEY:VALUE pairs (e.g. mirror_coef:4.0), got {pair!r}")
        parsed[key] = yaml.safe_load(value)
    return parsed


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument(
        "--algo", default="huri", choices=list(METHODS), help="method (RL Zoo algorithm name)"
    )
    parser.add_argument(
        "-conf",
        "--conf-file",
        type=Path,
        default=None,
        help="hyperparameter file (default: huri.yml, or a resumed run's)",
    )
    parser.add_argument(
        "-params",
        "--hyperparams",
        nargs="+",
        default=[],
        metavar="KEY:VALUE",
        help="replace preset entries, as rl_zoo3 train -params (VALUE read as YAML), e.g. mirror_coef:4.0; "
        "a resumed model is loaded with them",
    )
    parser.add_argument("-n", "--n-timesteps", type=int, default=None, help="override the preset's budget")
    parser.add_argument("--seed", type=int, default=None, help="default: 0, or a resumed run's")
    parser.add_argument("-f", "--log-folder", type=Path, default=Path("logs"))
    parser.add_argument(
        "--resume",
        type=Path,
        default=None,
        help="a run folder to continue (-n more steps, default: the rest of its budget; same curriculum)",
    )
    parser.add_argument("--checkpoint-freq", type=int, default=500_000, help="env steps between checkpoints")
    parser.add_argument("--threads", type=int, default=1, help="torch threads (1 is fastest for small nets)")
    parser.add_argument(
        "--device",
        default="auto",
        help="torch device of the networks, as rl_zoo3 train --device (auto: cuda where there is one); "
        "with 32 robots a GPU gains nothing over the CPU (docs/performance.md)",
    )
    parser.add_argument(
        "--workers",
        type=int,
        default=None,
        help="worker processes stepping robots (same results for any number; default: cores - 1; 0: none)",
    )
    parser.add_argument(
        "--physics-threads", type=int, default=1, help="threads stepping the physics of each process's robots"
    )
    parser.add_argument(
        "--curriculum-steps",
        type=int,
        default=None,
        help="grow the randomization from none to full over this many steps (default: the preset's callback)",
    )
    parser.add_argument("--curriculum-stages", type=int, default=8, help="stages of --curriculum-steps")
    parser.add_argument("--tensorboard-log", default=None)
    parser.add_argument(
        "--max-wall-minutes", type=float, default=None, help="stop (with a checkpoint) after this long"
    )
    args = parser.parse_args()
    th.set_num_threads(args.threads)

    if args.resume:
        if not (args.resume / f"{ENV_ID}.zip").is_file():
            parser.error(f"--resume {args.resume}: no {ENV_ID}.zip there (a run folder in RL Zoo's layout)")
        saved = args.resume / ENV_ID
        preset = yaml.safe_load((saved / "config.yml").read_text())
        saved_args = yaml.safe_load((saved / "args.yml").read_text())
        args.algo, args.seed = saved_args["algo"], saved_args["seed"] if args.seed is None else args.seed
    saved_preset = dict(preset) if args.resume else {}
    if args.conf_file is not None or not args.resume:
        preset = read_preset(ENV_ID, args.conf_file or DEFAULT_PRESET)
    try:
        preset = {**preset, **parse_hyperparams(args.hyperparams)}
        overrides = resume_overrides(saved_preset, preset) if args.resume else {}
    except ValueError as error:
        parser.error(str(error))
    args.seed = 0 if args.seed is None else args.seed
    budget = args.n_timesteps or int(preset["n_timesteps"])
    env_kwargs = dict(preset.get("env_kwargs") or {})
    scenario = get_scenario(env_kwargs.pop("scenario", "train"))
    run = args.resume or next_run_folder(args.log_folder, args.algo)
    normalizer = run / ENV_ID / "vecnormalize.pkl" if args.resume else None
    env = preset_env(
        preset,
        seed=args.seed,
        normalizer=normalizer,
        scenario=scenario,
        workers=args.workers,
        physics_threads=args.physics_threads,
    )
    state = RunState.read(run) if args.resume else RunState()
    if args.resume:
        if overrides:
            print(f"resuming with changed hyperparameters: {overrides}")
        model = HuRiPPO.load(
            run / f"{ENV_ID}.zip", env, device=args.device, tensorboard_log=args.tensorboard_log, **overrides
        )
        if state.timesteps != model.num_timesteps:
            print(f"warning: {run}: a model of {model.num_timesteps} steps, a state of {state.timesteps}")
        restore_random_states(run)
        if state.terrain_levels is not None:  # the terrain curriculum goes on from where its robots were
            start_on_levels(env, state.terrain_levels)
        env.seed(args.seed + model.num_timesteps)  # reproducible from this checkpoint ...
        model._last_obs = None  # ... from a reset: SB3 would go on from the observation saved with the model
        if args.n_timesteps is None:  # the rest of the preset's budget
            budget = max(budget - model.num_timesteps, 0)
    else:
        model = preset_model(
            preset,
            env,
            method=args.algo,
            seed=args.seed,
            device=args.device,
            tensorboard_log=args.tensorboard_log,
            verbose=1,
        )
    run_args = {
        "algo": args.algo,
        "env": ENV_ID,
        "seed": args.seed,
        "env_kwargs": {**env_kwargs, "scenario": scenario.name},
    }
    callbacks = get_callback_list(preset)  # the preset's `callback:` entries, read as RL Zoo reads them
    if args.curriculum_steps is not None:
        callbacks = [c for c in callbacks if not isinstance(c, RandomizationCurriculum)]
        callbacks.append(RandomizationCurriculum(args.curriculum_steps, args.curriculum_stages))
    curriculum = next((c for c in callbacks if isinstance(c, RandomizationCurriculum)), None)
    if curriculum is not None and state.curriculum_stage is not None:
        if not 0 <= state.curriculum_stage <= curriculum.stages:
            parser.error(
                f"the run reached curriculum stage {state.curriculum_stage}, beyond {curriculum.stages}"
            )
        curriculum.start_stage = state.curriculum_stage
    every = max(args.checkpoint_freq // env.num_envs, 1)
    callbacks.append(CheckpointCallback(every, str(run / "checkpoints"), save_vecnormalize=True))
    max_wall = None if args.max_wall_minutes is None else 60.0 * args.max_wall_minutes
    checkpoint = RunCheckpoint(run, preset, run_args, args.checkpoint_freq, curriculum, max_wall, verbose=1)
    callbacks.append(checkpoint)
    for stop in (signal.SIGTERM, signal.SIGINT):  # `kill` or Ctrl-C: stop at the next step, with a checkpoint
        signal.signal(stop, lambda *_: checkpoint.request_stop())
    print(f"Writing to {run}; callbacks: {', '.join(type(c).__name__ for c in callbacks)}")
    began = time.time()
    model.learn(
        budget,
        callback=CallbackList(callbacks),
        reset_num_timesteps=not args.resume,
    )
    print(f"{model.num_timesteps} steps in {time.time() - began:.0f} s; saved {run / (ENV_ID + '.zip')}")


if __name__ == "__main__":
    main()
