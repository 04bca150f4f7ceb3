"""How much of a training scenario an agent meets: its robot-steps and falls under each force it names.

A force cycle's later phases act only on robots that outlast its earlier ones, so what a policy trains on
depends on how long it stays up. This runs an agent's stochastic policy (as in training) on a scenario,
scaled like a curriculum stage, and counts robot-steps and falls by the force the force table names at
each robot's step: its target (centroid, hands, feet) and the range its magnitudes are drawn from (a
continuous 0-100 N apart from 150-200 N impulses). The work is done by
`study.analyses.force_exposure`.

    python -m study.scripts.force_exposure runs/huri/Zerith1-v0_1                    # robust at scale 1
    python -m study.scripts.force_exposure runs/huri/Zerith1-v0_1 --scale 0.95 --start-phases 0
"""

from __future__ import annotations

import argparse
from pathlib import Path

import torch as th

import zerith_gym
from sb3_huri.runner.folder import load_run
from study.analyses.force_exposure import exposure, exposure_table, training_scenario
from zerith_gym import ZERITH1_ID
from zerith_gym.core.scenarios import SCENARIOS


def main() -> None:
    """Parse the command line, run the agent on the scenario and print its exposure table."""
    formatter = argparse.RawDescriptionHelpFormatter
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=formatter)
    parser.add_argument("agent", type=Path, help="a run folder in RL Zoo's layout")
    parser.add_argument("--scenario", default="robust", choices=list(SCENARIOS))
    parser.add_argument("--scale", type=float, default=1.0, help="curriculum scale of the scenario")
    parser.add_argument("--start-phases", type=int, nargs="+", default=None, help="replace the cycle's")
    parser.add_argument("--robots", type=int, default=32)
    parser.add_argument("--steps", type=int, default=3000, help="control steps of every robot")
    parser.add_argument("--seed", type=int, default=5000)
    args = parser.parse_args()
    th.set_num_threads(1)
    try:
        scenario = training_scenario(args.scenario, args.scale, args.start_phases)
    except ValueError as error:
        parser.error(f"--start-phases: {error}")
    model, normalizer = load_run(args.agent, ZERITH1_ID)
    env = zerith_gym.make_vec_env(args.robots, seed=args.seed, scenario=scenario, workers=0)
    kinds, steps, falls = exposure(model, normalizer, env, args.steps)
    env.close()
    print(f"{args.agent} on {scenario.name}, {args.robots} robots x {args.steps} steps, stochastic policy")
    print(exposure_table(kinds, steps, falls))


if __name__ == "__main__":
    main()
