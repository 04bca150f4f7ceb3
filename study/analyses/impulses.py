"""Which single push an agent survives, and how Table 1's nine pushes an episode compound.

Table 1's sudden cases push every 2 s with U[150, 200] N for 0.1 s, and the same force acts on each body of
the target group: one body for the centroid, two for the hands and the feet, so a hand or foot push carries
twice the impulse of a centroid push. ``push`` reduces a sudden scenario to one push of a fixed force per
body from one of four directions (world frame; the robot walks along +x) at a chosen control step, and
``print_envelope`` counts the episodes that survive it, over pushes spread across one gait period (what a
push does depends on the gait's phase). ``falls_per_push`` counts, push by push, the robots standing when
each of a Table-1 episode's pushes came and those that fell before the next: an episode's survival is the
product of its per-push survivals. ``study.scripts.impulse_envelope`` is the command line.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import replace
from typing import Any

import numpy as np

from sb3_huri.runner.evaluation import TABLE1_SCENARIOS, evaluate
from zerith_gym.core.disturbances import ForceSchedule
from zerith_gym.core.randomization import NOMINAL
from zerith_gym.core.scenarios import SCENARIOS, Scenario
from zerith_gym.core.task import EPISODE_STEPS
from zerith_gym.zerith1.constants import CONTROL_DT, TOTAL_MASS
from zerith_gym.zerith1.gait import GAIT_PERIOD

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


def push_steps(phases: int) -> list[int]:
    """The control steps of `phases` pushes spread over one gait period from `PUSH_STEP` on."""
    period_steps = GAIT_PERIOD / CONTROL_DT
    return [PUSH_STEP + round(k * period_steps / phases) for k in range(phases)]


def print_envelope(
    model: Any,
    normalizer: Any | None,
    command: tuple[float, float, float],
    targets: Sequence[str],
    forces: Sequence[float],
    phases: int,
    robots: int,
    after: int,
    seed: int,
    test_ranges: bool,
) -> None:
    """Survival of one push per target, direction and force, over `phases` phases of the gait, `robots`
    episodes each, ending `after` control steps past the push; a table per target."""
    duration = PUSH_STEPS * CONTROL_DT
    steps = push_steps(phases)
    ranges = "test ranges" if test_ranges else "nominal robot"
    print(
        f"survival of one {duration:.1f}-s push at control step {steps}, command {command}, "
        f"{robots} robot(s) per step, seeds {seed}+, {ranges}"
    )
    for target in targets:
        bodies = 1 if target == "centroid" else 2
        impulses = [bodies * force * duration for force in forces]
        pairs = zip(forces, impulses, strict=True)
        header = " | ".join(f"{f:g} N ({j:g} N s, {j / TOTAL_MASS:.2f} m/s)" for f, j in pairs)
        print(f"\n| {target}: force per body | {header} |")
        print("|---" * (len(forces) + 1) + "|")
        for side, direction in DIRECTIONS.items():
            cells = []
            for force in forces:
                survived = [
                    evaluate(model, normalizer, push(target, force, direction, step, test_ranges), command,
                             robots, seed, episode_steps=step + after, workers=0)["survive"]
                    for step in steps
                ]  # fmt: skip
                cells.append(f"{np.mean(survived):.2f}")
            print(f"| {side} | " + " | ".join(cells) + " |", flush=True)
