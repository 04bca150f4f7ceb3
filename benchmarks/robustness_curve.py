"""The robustness learning curve of a long run: its checkpoints evaluated on the paper's Table-1 scenarios.

For every checkpoint of a run (`<run>/checkpoints/rl_model_<steps>_steps.zip` and its normalizer, written by
`examples/train_zerith.py`) at least `--every` steps after the last one evaluated, and for the run's newest
model, evaluates the deterministic policy on the six Table-1 scenarios (continuous and sudden forces on
centroid, hands and feet, at the test ranges and 1 m/s), on `side-impact` (one 200 N push from the side),
`nominal@1.0` and `nominal@0.5`, and appends a
row per checkpoint to `<run>/robustness.csv`: steps, the run's training wall time at that step (from
`curve.csv`) and the hardware it trained on (`state.json`), the survival rate of each case (`--episodes`
robots, seeds `--seed` + i, the same for every checkpoint), the Table-1 mean and the mean forward velocity
at 1 m/s.

    python benchmarks/robustness_curve.py runs/huri/Zerith1-v0_1                 # new checkpoints only
    python benchmarks/robustness_curve.py runs/huri/Zerith1-v0_1 --every 5000000 --episodes 10
"""

from __future__ import annotations

import argparse
import csv
import re
import tempfile
import time
from pathlib import Path

import torch as th

from sb3_huri.experiments.evaluation import TABLE1_SCENARIOS, evaluate, parse_case
from sb3_huri.zoo import load_run
from sb3_huri.zoo.checkpoints import RunState

ENV_ID = "Zerith1-v0"
CASES = (*TABLE1_SCENARIOS, "side-impact", "nominal@1.0", "nominal@0.5")
COLUMNS = ("timesteps", "wall_s", "hardware", *CASES, "table1_mean", "vx_at_1.0", "eval_s")


def checkpoints(run: Path) -> dict[int, tuple[Path, Path]]:
    """Model and normalizer of each saved checkpoint, by step; the run's newest model included."""
    found = {}
    for model in (run / "checkpoints").glob("rl_model_*_steps.zip"):
        steps = int(re.findall(r"_(\d+)_steps", model.name)[0])
        found[steps] = (model, run / "checkpoints" / f"rl_model_vecnormalize_{steps}_steps.pkl")
    newest = RunState.read(run).timesteps
    if newest and (run / f"{ENV_ID}.zip").is_file():
        found[newest] = (run / f"{ENV_ID}.zip", run / ENV_ID / "vecnormalize.pkl")
    return dict(sorted(found.items()))


def wall_time_at(run: Path, steps: int) -> float:
    """The run's training wall time when it reached `steps` (the curve's nearest row at or before it)."""
    wall = 0.0
    with (run / "curve.csv").open() as file:
        for row in csv.DictReader(file):
            if int(row["timesteps"]) > steps:
                break
            wall = float(row["wall_s"])
    return wall


def training_hardware(run: Path, steps: int) -> str:
    """The hardware of the training session that reached `steps` (`state.json`)."""
    for session in RunState.read(run).sessions:
        if session["from_timesteps"] < steps <= session.get("to_timesteps", steps):
            return session["hardware"]
    return "unknown"


def evaluate_checkpoint(
    model_file: Path, normalizer_file: Path, episodes: int, seed: int
) -> dict[str, float]:
    """Survival per case, the Table-1 mean and the mean forward velocity at 1 m/s."""
    with tempfile.TemporaryDirectory() as folder:  # RL Zoo's layout, which load_run reads
        layout = Path(folder)
        (layout / ENV_ID).mkdir()
        (layout / f"{ENV_ID}.zip").symlink_to(model_file.resolve())
        (layout / ENV_ID / "vecnormalize.pkl").symlink_to(normalizer_file.resolve())
        model, normalizer = load_run(layout, ENV_ID)
    row: dict[str, float] = {}
    for case in CASES:
        scenario, command = parse_case(case)
        metrics = evaluate(model, normalizer, scenario, command, episodes, seed)
        row[case] = round(metrics["survive"], 3)
        if case == "nominal@1.0":
            row["vx_at_1.0"] = round(metrics["vx"], 3)
    row["table1_mean"] = round(sum(row[c] for c in TABLE1_SCENARIOS) / len(TABLE1_SCENARIOS), 3)
    return row


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("run", type=Path, help="a run folder written by examples/train_zerith.py")
    parser.add_argument(
        "--every", type=int, default=5_000_000, help="env steps between evaluated checkpoints"
    )
    parser.add_argument("--episodes", type=int, default=10)
    parser.add_argument("--seed", type=int, default=1000)
    args = parser.parse_args()
    th.set_num_threads(1)
    output = args.run / "robustness.csv"
    done: list[int] = []
    if output.is_file():
        with output.open() as file:
            done = [int(row["timesteps"]) for row in csv.DictReader(file)]
    last = max(done, default=-args.every)
    newest = max(checkpoints(args.run), default=None)
    for steps, (model_file, normalizer_file) in checkpoints(args.run).items():
        if steps in done or (steps - last < args.every and steps != newest):
            continue
        began = time.time()
        row = evaluate_checkpoint(model_file, normalizer_file, args.episodes, args.seed)
        trained = {"timesteps": steps, "wall_s": wall_time_at(args.run, steps)}
        trained["hardware"] = training_hardware(args.run, steps)
        row = {**trained, **row, "eval_s": round(time.time() - began)}
        new = not output.is_file()
        with output.open("a", newline="") as file:
            writer = csv.DictWriter(file, fieldnames=COLUMNS)
            if new:
                writer.writeheader()
            writer.writerow(row)
        print(row, flush=True)
        last = steps


if __name__ == "__main__":
    main()
