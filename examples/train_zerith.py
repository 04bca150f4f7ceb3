"""Train Zerith-1 to walk with HuRi (or another method) on the batched environment, on a CPU.

    python examples/train_zerith.py                                   # HuRi (huri), the CPU preset
    python examples/train_zerith.py --algo huri-baseline --seed 1     # PPO baseline, same networks
    python examples/train_zerith.py --resume logs/huri/Zerith1-v0_1   # continue where it stopped
    python examples/train_zerith.py --resume logs/huri/Zerith1-v0_1 -params mirror_coef:4.0
    python examples/train_zerith.py -conf hyperparams/huri_robust.yml --max-wall-minutes 150

It trains what `rl_zoo3 train --algo <algo> --env Zerith1-v0` trains: the `Zerith1-v0` preset of
`hyperparams/huri.yml` on the batched env (`zerith_gym.make_vec_env`: a slice of robots per core),
with the preset's `callback:` entries read as RL Zoo reads them: the reward-term logs
(`zerith_gym.sb3.callbacks.RewardTermsLogger`) and the randomization curriculum
(`zerith_gym.sb3.callbacks.RandomizationCurriculum`, which grows the randomization from none to the full
training ranges; `--curriculum-steps N` replaces it), or on terrains (`-conf hyperparams/huri_terrain.yml`)
the terrain curriculum (`zerith_gym.sb3.callbacks.TerrainCurriculum`). It adds resuming and periodic
checkpoints. The run is
written in RL Zoo's layout (`<log-folder>/<algo>/Zerith1-v0_<id>/Zerith1-v0.zip` with
`Zerith1-v0/config.yml`, `args.yml` and `vecnormalize.pkl`), so RL Zoo's tools read it:

    rl_zoo3 enjoy --algo huri --env Zerith1-v0 -f logs/ --no-render -n 1000
    python examples/watch_zerith.py logs/huri/Zerith1-v0_1

The trainer is `sb3_huri.runner.train_run`, the one the training campaign uses
(`python -m study campaign`). At the first rollout boundary past every `--checkpoint-freq`
steps and at the end, the run folder gets its newest checkpoint: model, normalizer, random states,
curriculum stage, terrain levels and the sessions' wall time, and `curve.csv` a row per rollout;
`<run>/checkpoints/` keeps a copy every `--keep-every` steps, and `--robustness-every` adds a row of
Table-1 survival to `<run>/robustness.csv` as training passes each multiple.
`--resume` continues from the newest checkpoint, so a run can train over many sessions (`kill` or Ctrl-C
stops it after the rollout under way, with a checkpoint; a hard stop loses at most `--checkpoint-freq`
steps).
TensorBoard logs include the episode sums of every reward term (`terms/<name>`) and the fall rate.
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

import yaml

from sb3_huri.huri.methods import DEFAULT_METHOD
from sb3_huri.runner.files import RunError
from sb3_huri.runner.folder import next_run_folder
from sb3_huri.runner.training import RobustnessSchedule, RunRequest, TrainingOptions, train_run
from sb3_huri.zoo import METHODS, read_preset
from zerith_gym import ZERITH1_ID

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


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    add = parser.add_argument
    add(
        "--algo",
        default=None,
        choices=list(METHODS),
        help=f"method (RL Zoo algorithm name; default {DEFAULT_METHOD})",
    )
    add(
        "-conf",
        "--conf-file",
        type=Path,
        default=None,
        help="hyperparameter file (default: huri.yml, or a resumed run's)",
    )
    add(
        "-params",
        "--hyperparams",
        nargs="+",
        default=[],
        metavar="KEY:VALUE",
        help="replace preset entries, as rl_zoo3 train -params (VALUE read as YAML), e.g. mirror_coef:4.0; "
        "a resumed model is loaded with them",
    )
    add(
        "-n",
        "--n-timesteps",
        type=int,
        default=None,
        help="steps to train (default: the rest of the preset's budget)",
    )
    add("--seed", type=int, default=None, help="default: 0, or a resumed run's")
    add("-f", "--log-folder", type=Path, default=Path("logs"))
    add(
        "--resume", type=Path, default=None, help="a run folder to continue (its method, seed and curriculum)"
    )
    add("--checkpoint-freq", type=int, default=500_000, help="env steps between checkpoints")
    add(
        "--keep-every",
        type=int,
        default=None,
        help="env steps between kept checkpoint copies (default: --checkpoint-freq)",
    )
    add(
        "--robustness-every", type=int, default=None, help="env steps between robustness rows (default: none)"
    )
    add("--threads", type=int, default=1, help="torch threads (1 is fastest for small nets)")
    add(
        "--device",
        default="auto",
        help="torch device of the networks, as rl_zoo3 train --device (auto: cuda where there is one); "
        "with 32 robots a GPU gains nothing over the CPU (docs/performance.md)",
    )
    add(
        "--workers",
        type=int,
        default=None,
        help="worker processes stepping robots (same results for any number; default: cores - 1; 0: none)",
    )
    add(
        "--physics-threads", type=int, default=1, help="threads stepping the physics of each process's robots"
    )
    add(
        "--curriculum-steps",
        type=int,
        default=None,
        help="grow the randomization from none to full over this many steps (default: the preset's callback)",
    )
    add("--curriculum-stages", type=int, default=8, help="stages of --curriculum-steps")
    add("--tensorboard-log", default=None)
    add("--max-wall-minutes", type=float, default=None, help="stop (with a checkpoint) after this long")
    return parser  # fmt: skip


def main() -> None:
    parser = build_parser()
    args = parser.parse_args()
    if args.resume and not (args.resume / f"{ZERITH1_ID}.zip").is_file():
        parser.error(f"--resume {args.resume}: no {ZERITH1_ID}.zip there (a run folder in RL Zoo's layout)")
    preset = None
    if args.conf_file is not None or not args.resume:
        preset = read_preset(ZERITH1_ID, args.conf_file or DEFAULT_PRESET)
    curriculum = None if args.curriculum_steps is None else (args.curriculum_steps, args.curriculum_stages)
    try:
        request = RunRequest(
            run=args.resume or next_run_folder(args.log_folder, args.algo or DEFAULT_METHOD),
            preset=preset, method=args.algo, seed=args.seed, hyperparams=parse_hyperparams(args.hyperparams),
            more_steps=args.n_timesteps, curriculum=curriculum,
        )  # fmt: skip
        options = TrainingOptions(
            checkpoint_freq=args.checkpoint_freq,
            keep_every=args.keep_every or args.checkpoint_freq,
            robustness=RobustnessSchedule(args.robustness_every) if args.robustness_every else None,
            max_wall_s=None if args.max_wall_minutes is None else 60.0 * args.max_wall_minutes,
            device=args.device, workers=args.workers, physics_threads=args.physics_threads,
            threads=args.threads, tensorboard_log=args.tensorboard_log,
        )  # fmt: skip
        train_run(request, options)
    except (ValueError, RunError) as error:  # a bad request; a run folder another trainer holds, or damaged
        parser.error(str(error))


if __name__ == "__main__":
    main()
