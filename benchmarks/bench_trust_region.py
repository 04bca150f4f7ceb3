"""PPO's trust region on Zerith1-v0: learning-rate arms side by side, several seeds, from scratch.

Each arm trains HuRiPPO from scratch with a preset (default: the robust preset, `hyperparams/huri_robust.yml`)
with some of its entries replaced, in a fixed scenario (no curriculum), and records per update the
approximate KL, the clip fraction, the critic's explained variance, the action noise, the learning rates and
the mean training episode length. The arms:

- `shared`: one learning rate (3e-4) for actor and critic, no KL control (the walking preset's update);
- `kl-shared`: `desired_kl` (default 0.01) adapting the one rate that actor and critic share;
- `kl-actor`: `desired_kl` adapting the actor's rate only; the critic at its own 3e-4;
- `kl-actor-mirror`: `kl-actor` with a symmetry loss on the actor (`mirror_coef`, default 1; `--mirror-coef`).

    python benchmarks/bench_trust_region.py --steps 300000 --seeds 0 1 --output trust.jsonl
    python benchmarks/bench_trust_region.py --arms kl-actor kl-actor-mirror --desired-kl 0.007 --mirror-coef 4
    python benchmarks/bench_trust_region.py --summary trust.jsonl     # the table of a finished file

The summary gives, per arm, the mean over seeds of each run's median over its updates (and the runs'
range), the mean episode length over the first and last 10% of each run, the mean return over the last
10%, and the actor's asymmetry at the end (`sb3_huri.common.mirror.mirror_loss` on the last rollout).
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np
import torch as th

from sb3_huri.common.mirror import mirror_loss
from sb3_huri.runner.build import preset_env, preset_model
from sb3_huri.runner.curve import UpdateRecorder
from sb3_huri.zoo import read_preset
from zerith_gym.core.scenarios import get_scenario, scaled_scenario

REPO = Path(__file__).resolve().parents[1]
ENV_ID = "Zerith1-v0"
ARMS: dict[str, dict] = {
    "shared": {"desired_kl": None, "critic_learning_rate": None, "learning_rate": 3e-4},
    "kl-shared": {"desired_kl": 0.01, "critic_learning_rate": None, "learning_rate": 3e-4},
    "kl-actor": {"desired_kl": 0.01, "critic_learning_rate": 3e-4, "learning_rate": 3e-4},
    "kl-actor-mirror": {
        "desired_kl": 0.01,
        "critic_learning_rate": 3e-4,
        "learning_rate": 3e-4,
        "mirror_coef": 1,
    },
}


def train_arm(
    preset_file: Path,
    arm: str,
    seed: int,
    steps: int,
    scenario: str,
    scale: float,
    desired_kl: float,
    mirror_coef: float | None = None,
) -> dict:
    """Train one arm from scratch for `steps` steps and return its per-update rows."""
    preset = read_preset(ENV_ID, preset_file)
    overrides = dict(ARMS[arm])
    if overrides["desired_kl"] is not None:
        overrides["desired_kl"] = desired_kl
    if "mirror_coef" in overrides and mirror_coef is not None:
        overrides["mirror_coef"] = mirror_coef
    env = preset_env(preset, seed=seed, scenario=scaled_scenario(get_scenario(scenario), scale))
    model = preset_model(preset, env, seed=seed, device="cpu", **overrides)
    recorder = UpdateRecorder()
    began = time.time()
    model.learn(steps, callback=recorder)
    actor_obs = model.rollout_buffer.observations["policy"].reshape(
        -1, model.rollout_buffer.obs_shape["policy"][0]
    )
    with th.no_grad():  # how far the actor is from acting symmetrically, on the last rollout's observations
        asymmetry = mirror_loss(model.policy.actor_mean, th.as_tensor(actor_obs), *model.mirror_maps()).item()
    env.close()
    return {
        "arm": arm,
        "seed": seed,
        "desired_kl": overrides["desired_kl"],
        "mirror_coef": overrides.get("mirror_coef", 0.0),
        "steps": steps,
        "scenario": f"{scenario}x{scale:g}",
        "wall_s": round(time.time() - began, 1),
        "asymmetry": asymmetry,
        "rows": recorder.rows,
    }


def summarize(results: list[dict]) -> str:
    """Per arm: mean over seeds of each run's median per update, with the runs' range; episode lengths."""
    header = (
        "| arm | seeds | approx_kl | clip fraction | explained var. | std | ep len first -> last 10% "
        "| return, last 10% | asymmetry at the end |"
    )
    lines = [header, "|---|---|---|---|---|---|---|---|---|"]

    def setting(r: dict) -> tuple:
        return r["arm"], r.get("desired_kl"), r.get("mirror_coef") or 0.0

    for arm, kl, mirror in dict.fromkeys(setting(r) for r in results):
        runs = [r for r in results if setting(r) == (arm, kl, mirror)]
        cells = []
        for key in ("approx_kl", "clip_fraction", "explained_variance", "std"):
            medians = [float(np.median([row[key] for row in r["rows"]])) for r in runs]
            cells.append(f"{np.mean(medians):.3g} ({min(medians):.3g}-{max(medians):.3g})")
        first, last, returns = [], [], []
        for r in runs:
            lengths = np.array([row["ep_len"] for row in r["rows"]])
            tenth = max(len(lengths) // 10, 1)
            first.append(np.nanmean(lengths[:tenth]))
            last.append(np.nanmean(lengths[-tenth:]))
            returns.append(np.nanmean([row["ep_return"] for row in r["rows"]][-tenth:]))
        asymmetry = [r["asymmetry"] for r in runs if "asymmetry" in r]
        seeds = ", ".join(str(r["seed"]) for r in runs)
        name = (arm if kl is None else f"{arm} {kl:g}") + (f", mirror {mirror:g}" if mirror else "")
        lengths = f"{np.mean(first):.0f} -> {np.mean(last):.0f} ({min(last):.0f}-{max(last):.0f})"
        returns_cell = f"{np.mean(returns):.1f} ({min(returns):.1f}-{max(returns):.1f})"
        asymmetry_cell = f"{np.mean(asymmetry):.2g}" if asymmetry else "-"
        lines.append(
            f"| {name} | {seeds} | {' | '.join(cells)} | {lengths} | {returns_cell} | {asymmetry_cell} |"
        )
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--preset", type=Path, default=REPO / "hyperparams" / "huri_robust.yml")
    parser.add_argument("--arms", nargs="+", default=list(ARMS), choices=list(ARMS))
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1])
    parser.add_argument("--steps", type=int, default=300_000)
    parser.add_argument("--desired-kl", type=float, default=0.01, help="KL target of the kl-* arms")
    parser.add_argument("--mirror-coef", type=float, default=None, help="mirror_coef of the mirror arm")
    parser.add_argument("--scenario", default="train")
    parser.add_argument(
        "--scale", type=float, default=1.0, help="randomization and force scale of the scenario"
    )
    parser.add_argument("--output", type=Path, default=None, help="append one JSON line per run here")
    parser.add_argument("--summary", type=Path, default=None, help="only print the table of this file")
    args = parser.parse_args()
    if args.summary:
        print(summarize([json.loads(line) for line in args.summary.read_text().splitlines()]))
        return
    th.set_num_threads(1)
    results = []
    for seed in args.seeds:
        for arm in args.arms:
            settings = (args.scenario, args.scale, args.desired_kl, args.mirror_coef)
            result = train_arm(args.preset, arm, seed, args.steps, *settings)
            results.append(result)
            print(json.dumps({k: v for k, v in result.items() if k != "rows"}), flush=True)
            if args.output:
                with args.output.open("a") as file:
                    file.write(json.dumps(result) + "\n")
    print(summarize(results))


if __name__ == "__main__":
    main()
