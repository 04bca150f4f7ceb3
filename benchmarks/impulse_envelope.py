"""Which single push an agent survives: survival against the impulse, per force target and direction.

Table 1's sudden cases push every 2 s with U[150, 200] N for 0.1 s, and the same force acts on each body of
the target group: one body for the centroid, two for the hands and the feet, so a hand or foot push carries
twice the impulse of a centroid push. This gives a walking agent one push of 0.1 s, of a fixed force per body,
from one of four directions (world frame; the robot walks along +x), and counts the episodes that end
without a fall within `--after` control steps of the push (default 3 s). What a push does depends on the
gait's phase when it comes (which foot is on the ground), so each cell pushes at `--phases` times spread
over one gait period from 2 s on, `--robots` robots each. The robot is the nominal one (one robot per phase
is then enough: the episodes are deterministic) unless `--test-ranges` (Table 1's load, friction and CoM
ranges). `--stand` gives the same pushes to a robot that holds its default stance (zero action, zero
command): the reference a policy should beat.

Each cell reports the survival share over phases and robots; the header gives the total impulse (N s) and
the velocity change it would give the whole nominal robot (impulse / 36 kg).

`--table1` measures the same in Table 1's own sudden episodes instead: a 20-s episode holds nine pushes
(every 2 s from 2 s on), so its survival is the product of nine per-push survivals. For each sudden case it
runs `--robots` episodes and counts, push by push, the robots standing when it came and those that fell
before the next one: the per-push survival, and the episode survival it compounds to.

    python benchmarks/impulse_envelope.py runs/huri/Zerith1-v0_1
    python benchmarks/impulse_envelope.py runs/huri/Zerith1-v0_1 --stand --forces 25 50 100
    python benchmarks/impulse_envelope.py runs/huri/Zerith1-v0_1 --table1 --robots 100
"""

from __future__ import annotations

import argparse
import math
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import torch as th

from sb3_huri.experiments.evaluation import TABLE1_SCENARIOS, HoldStance, evaluate
from sb3_huri.zoo import load_run
from zerith_gym.disturbances import FORCE_TARGETS, ForceSchedule
from zerith_gym.gait import GAIT_PERIOD
from zerith_gym.randomization import NOMINAL
from zerith_gym.robot import CONTROL_DT, TOTAL_MASS
from zerith_gym.scenarios import SCENARIOS, TEST_COMMAND, Scenario
from zerith_gym.task import EPISODE_STEPS

DIRECTIONS = {
    "from behind": 0.0,
    "from the front": math.pi,
    "from the right": math.pi / 2,
    "from the left": -math.pi / 2,
}
"""World-frame direction of the force (rad from +x towards +y) for each side the push comes from."""
PUSH_STEP = 100
"""The earliest push comes at 2 s, as Table 1's first impulse does."""
PUSH_STEPS = 5
"""It lasts 0.1 s, as Table 1's impulses do."""


def push(target: str, force: float, direction: float, step: int, test_ranges: bool) -> Scenario:
    """Table 1's sudden scenario on `target`, reduced to one push of `force` N per body from `direction`
    at control step `step`."""
    scenario = SCENARIOS[f"sudden-{target}"]
    schedule = ForceSchedule(
        target,
        (force, force),
        period_steps=10_000,
        duration_steps=PUSH_STEPS,
        start_step=step,
        direction=direction,
    )
    ranges = scenario.randomization if test_ranges else NOMINAL
    return replace(scenario, name=f"push-{target}", randomization=ranges, force=schedule)


def falls_per_push(
    model: Any, normalizer: Any | None, scenario: Scenario, robots: int, seed: int
) -> np.ndarray:
    """Run `robots` episodes of `scenario` (a sudden one, with its own command) and count, for each push of
    its schedule, the robots standing when it came and those that fell before the next: array (pushes, 2)."""
    schedule = scenario.force
    result = evaluate(model, normalizer, scenario, None, robots, seed, workers=0, per_robot=True)
    fall_step = np.nan_to_num(result["fall_step"], nan=EPISODE_STEPS)
    starts = np.arange(schedule.start_step, EPISODE_STEPS, schedule.period_steps)
    ends = np.append(starts[1:], EPISODE_STEPS)
    pairs = zip(starts, ends, strict=True)
    return np.array([[(fall_step >= a).sum(), ((fall_step >= a) & (fall_step < b)).sum()] for a, b in pairs])


def print_table1(model: Any, normalizer: Any | None, robots: int, seed: int) -> None:
    """Per-push survival in each sudden Table-1 case, and the episode survival it compounds to."""
    print(f"Table 1's sudden cases, {robots} episodes each, seeds {seed}+")
    print("| case | fell before push 1 | standing / fell at each push | per push | compounded | survived |")
    print("|---|---|---|---|---|---|")
    for case in (c for c in TABLE1_SCENARIOS if c.startswith("sudden")):
        counts = falls_per_push(model, normalizer, SCENARIOS[case], robots, seed)
        standing, fell = counts[:, 0], counts[:, 1]
        per_push = 1.0 - fell.sum() / max(standing.sum(), 1)
        pushes = " ".join(f"{a}/{f}" for a, f in counts)
        survived = (standing[-1] - fell[-1]) / robots
        compounded = f"^{len(counts)}: {per_push ** len(counts):.2f}"
        row = (
            f"| {case} | {robots - standing[0]} | {pushes} | {per_push:.3f} | {compounded} | {survived:.2f} |"
        )
        print(row, flush=True)


def print_envelope(
    model: Any, normalizer: Any | None, command: tuple[float, float, float], args: Any
) -> None:
    """Survival of one push per target, direction and force, over phases of the gait."""
    duration = PUSH_STEPS * CONTROL_DT
    period_steps = GAIT_PERIOD / CONTROL_DT
    push_steps = [PUSH_STEP + round(k * period_steps / args.phases) for k in range(args.phases)]
    ranges = "test ranges" if args.test_ranges else "nominal robot"
    print(
        f"survival of one {duration:.1f}-s push at control step {push_steps}, command {command}, "
        f"{args.robots} robot(s) per step, seeds {args.seed}+, {ranges}"
    )
    for target in args.targets:
        bodies = 1 if target == "centroid" else 2
        impulses = [bodies * force * duration for force in args.forces]
        pairs = zip(args.forces, impulses, strict=True)
        header = " | ".join(f"{f:g} N ({j:g} N s, {j / TOTAL_MASS:.2f} m/s)" for f, j in pairs)
        print(f"\n| {target}: force per body | {header} |")
        print("|---" * (len(args.forces) + 1) + "|")
        for side, direction in DIRECTIONS.items():
            cells = []
            for force in args.forces:
                survived = [
                    evaluate(model, normalizer, push(target, force, direction, step, args.test_ranges),
                             command, args.robots, args.seed, episode_steps=step + args.after,
                             workers=0)["survive"]
                    for step in push_steps
                ]  # fmt: skip
                cells.append(f"{np.mean(survived):.2f}")
            print(f"| {side} | " + " | ".join(cells) + " |", flush=True)


def main() -> None:
    formatter = argparse.RawDescriptionHelpFormatter
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=formatter)
    parser.add_argument("agent", type=Path, help="a run folder in RL Zoo's layout")
    parser.add_argument("--targets", nargs="+", default=list(FORCE_TARGETS), choices=list(FORCE_TARGETS))
    parser.add_argument("--forces", type=float, nargs="+", default=[100.0, 150.0, 200.0, 250.0, 300.0])
    parser.add_argument("--phases", type=int, default=8, help="push times per cell, over one gait period")
    parser.add_argument("--robots", type=int, default=1, help="episodes per phase; robot i seeded seed + i")
    parser.add_argument("--after", type=int, default=150, help="control steps from the push to the end")
    parser.add_argument("--seed", type=int, default=1000)
    parser.add_argument("--test-ranges", action="store_true", help="Table 1's load, friction and CoM ranges")
    parser.add_argument("--stand", action="store_true", help="zero action and zero command instead")
    parser.add_argument("--table1", action="store_true", help="per-push survival in Table 1's sudden cases")
    args = parser.parse_args()
    if min(args.robots, args.phases) < 1 or args.after <= PUSH_STEPS:
        parser.error(f"need --robots >= 1, --phases >= 1 and --after > {PUSH_STEPS} (the push's length)")
    if any(force <= 0 for force in args.forces):
        parser.error(f"--forces must be positive (N per body), got {args.forces}")
    th.set_num_threads(1)
    model, normalizer = load_run(args.agent, "Zerith1-v0")
    command = TEST_COMMAND
    if args.stand:
        model, normalizer, command = HoldStance(), None, (0.0, 0.0, 0.0)
    if args.table1:
        print_table1(model, normalizer, args.robots, args.seed)
    else:
        print_envelope(model, normalizer, command, args)


if __name__ == "__main__":
    main()
