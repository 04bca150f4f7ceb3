"""How much of a training scenario an agent meets: its robot-steps and falls under each force it names.

A force cycle's later phases act only on robots that outlast its earlier ones, so what a policy trains on
depends on how long it stays up. This runs an agent's stochastic policy (as in training) on a scenario,
scaled like a curriculum stage, and counts robot-steps and falls by the force the force table names at
each robot's step: its target (centroid, hands, feet) and the range its magnitudes are drawn from (a
continuous 0-100 N apart from 150-200 N impulses).

    python benchmarks/force_exposure.py runs/huri/Zerith1-v0_1                    # robust at scale 1
    python benchmarks/force_exposure.py runs/huri/Zerith1-v0_1 --scale 0.95 --start-phases 0
"""

from __future__ import annotations

import argparse
from dataclasses import replace
from pathlib import Path

import numpy as np
import torch as th

import zerith_gym
from sb3_huri.zoo import load_run
from zerith_gym.disturbances import FORCE_TARGETS, ForceCycle
from zerith_gym.scenarios import SCENARIOS, scaled_scenario


def exposure(model, normalizer, env, num_steps: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Run `model`'s stochastic policy on the batched `env` for `num_steps` steps. Returns the kinds of force
    its scenario's table names, (k, 3) rows of target index and magnitude range, and the robot-steps and
    falls under each (a fall counts under the force of its last step)."""
    task = env.robots.task
    forces = np.stack([task.arrays.force_target, *task.arrays.force_magnitude.T], axis=1)
    kinds, kind_of_step = np.unique(forces, axis=0, return_inverse=True)
    kind_of_step = kind_of_step.ravel()
    steps, falls = np.zeros(len(kinds), dtype=int), np.zeros(len(kinds), dtype=int)
    obs = env.reset()
    for _ in range(num_steps):
        state = task.state
        kind = kind_of_step[state.step_count + state.force_offset]
        np.add.at(steps, kind, 1)
        actions, _ = model.predict(normalizer.normalize_obs(obs) if normalizer else obs, deterministic=False)
        obs, _, dones, infos = env.step(actions)
        for i in np.flatnonzero(dones):
            falls[kind[i]] += bool(infos[i]["fall"])
    return kinds, steps, falls


def main() -> None:
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
    scenario = scaled_scenario(SCENARIOS[args.scenario], args.scale)
    if args.start_phases is not None:
        if not isinstance(scenario.force, ForceCycle):
            parser.error(f"--start-phases: {args.scenario!r} has no force cycle")
        scenario = replace(scenario, force=replace(scenario.force, start_phases=tuple(args.start_phases)))
    model, normalizer = load_run(args.agent, "Zerith1-v0")
    env = zerith_gym.make_vec_env(args.robots, seed=args.seed, scenario=scenario, workers=0)
    kinds, steps, falls = exposure(model, normalizer, env, args.steps)
    env.close()
    print(f"{args.agent} on {scenario.name}, {args.robots} robots x {args.steps} steps, stochastic policy")
    print("| target | force (N) | share of robot-steps | falls | falls per 1,000 robot-steps |")
    print("|---|---|---|---|---|")
    targets = list(FORCE_TARGETS)
    for (target, low, high), kind_steps, kind_falls in zip(kinds, steps, falls, strict=True):
        rate = 1000 * kind_falls / kind_steps if kind_steps else float("nan")
        share = f"{kind_steps / steps.sum():.3f}"
        print(f"| {targets[int(target)]} | {low:.0f}-{high:.0f} | {share} | {kind_falls:.0f} | {rate:.2f} |")


if __name__ == "__main__":
    main()
