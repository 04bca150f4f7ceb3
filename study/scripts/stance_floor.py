"""What the paper's test forces do to a robot that only holds its posture: a physical floor for Table 1.

Each of the six Table-1 scenarios and `side-impact` is run with the zero action (the PD controllers hold
the default stance) and a zero command, so no policy is involved: the share of 20-s episodes that end in a
fall and the median step of a fall, with the test ranges (load, friction, CoM offset) as the scenario has
them, with the nominal robot, and with one test range at a time (`--one-range-at-a-time`). Where a robot
that stands still survives a force, a falling agent has not learned to bear it; where the standing robot
falls too, the agent must step or lean against it.

    python -m study.scripts.stance_floor                                # 20 robots per row, seeds 1000+
    python -m study.scripts.stance_floor --robots 50 --one-range-at-a-time --cases sudden-feet continuous-feet
"""

from __future__ import annotations

import argparse
from dataclasses import replace

import numpy as np

from sb3_huri.runner.evaluation import TABLE1_SCENARIOS, HoldStance, evaluate
from zerith_gym.core.randomization import NOMINAL
from zerith_gym.core.scenarios import SCENARIOS, Scenario

RANGES = ("added_mass", "friction", "com_offset")
"""The test ranges the Table-1 scenarios widen beyond the nominal robot."""


def stand(scenario: Scenario, robots: int, seed: int) -> tuple[float, float]:
    """Share of `robots` episodes of `scenario` (zero action, zero command) that end in a fall, and the
    median control step of those falls (NaN when none fell)."""
    result = evaluate(HoldStance(), None, scenario, (0.0, 0.0, 0.0), robots, seed, workers=0, per_robot=True)
    fall_step = result["fall_step"]
    fell = ~np.isnan(fall_step)
    return float(fell.mean()), float(np.median(fall_step[fell])) if fell.any() else float("nan")


def variants(name: str, one_range_at_a_time: bool) -> list[tuple[str, Scenario]]:
    """The scenario `name` standing still: with its test ranges, the nominal robot, one range at a time."""
    scenario = replace(SCENARIOS[name], command=None)
    rows = [("test ranges", scenario), ("nominal robot", replace(scenario, randomization=NOMINAL))]
    if one_range_at_a_time:
        for entry in RANGES:
            ranges = replace(NOMINAL, **{entry: getattr(scenario.randomization, entry)})
            rows.append((f"{entry} only", replace(scenario, randomization=ranges)))
    return rows


def main() -> None:
    formatter = argparse.RawDescriptionHelpFormatter
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=formatter)
    cases = [*TABLE1_SCENARIOS, "side-impact"]
    parser.add_argument("--cases", nargs="+", default=cases, choices=list(SCENARIOS), help="scenarios")
    parser.add_argument("--robots", type=int, default=20, help="episodes per row (default 20)")
    parser.add_argument("--seed", type=int, default=1000, help="robot i is seeded with seed + i")
    parser.add_argument("--one-range-at-a-time", action="store_true", help="also each test range alone")
    args = parser.parse_args()
    if args.robots < 1:
        parser.error(f"--robots must be at least 1, got {args.robots}")
    print("| scenario (zero action, zero command) | ranges | falls | median fall step |")
    print("|---|---|---|---|")
    for name in args.cases:
        for label, scenario in variants(name, args.one_range_at_a_time):
            falls, median = stand(scenario, args.robots, args.seed)
            step = "-" if np.isnan(median) else f"{median:.0f}"
            print(f"| {name} | {label} | {falls:.2f} | {step} |", flush=True)


if __name__ == "__main__":
    main()
