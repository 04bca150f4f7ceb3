"""Tile terrains on both backends: do MJX's height-field contacts give the CPU backend's trajectories?

    python -m study.scripts.mjx_terrain                     # the shipped HuRi agent, 12 robots, 200 steps
    python -m study.scripts.mjx_terrain --agent runs/huri/Zerith1-v0_1 --robots 24

Robots start at the centres of the tiles of the paper's four kinds (`PAPER_TILE_KINDS`) at three levels (no
spawn jitter, no randomization, so both backends start from the same states) and walk at 0.5 m/s with the
agent's deterministic policy. Printed per backend: the step of each robot's first fall (- for none); and
the first step at which the two backends' policy observations part by more than 0.05 (the agent's inputs:
a different ground under the feet shows there first). docs/gpu.md has the figures.
"""

from __future__ import annotations

import argparse
from dataclasses import replace
from pathlib import Path

import numpy as np

import zerith_gym
from sb3_huri.runner.folder import load_run
from zerith_gym.core.scenarios import Scenario
from zerith_gym.terrain.ground import tile_terrain
from zerith_gym.terrain.tiles import PAPER_TILE_KINDS

ROOT = Path(__file__).resolve().parent.parent


def rollout(backend: str, agent: Path, robots: int, steps: int) -> tuple[np.ndarray, np.ndarray]:
    """Policy observations (steps, robots, 46) and each robot's first fall step (-1: none)."""
    terrain = replace(tile_terrain(kinds=PAPER_TILE_KINDS, levels=3, start_levels=3), spawn_jitter=0.0)
    scenario = Scenario("tiles-nominal", terrain=terrain)
    options = {"workers": 0} if backend == "cpu" else {}
    env = zerith_gym.make_vec_env(
        robots, seed=0, scenario=scenario, command=(0.5, 0.0, 0.0), backend=backend, **options
    )
    model, normalizer = load_run(agent, "Zerith1-v0")
    obs = env.reset()
    seen = np.zeros((steps, robots, 46))
    fall = np.full(robots, -1)
    for t in range(steps):
        seen[t] = obs["policy"]
        action, _ = model.predict(normalizer.normalize_obs(obs) if normalizer else obs, deterministic=True)
        obs, _, _, infos = env.step(action)
        fell = np.array([info["fall"] for info in infos]) & (fall < 0)
        fall[fell] = t + 1
    env.close()
    return seen, fall


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--agent", type=Path, default=ROOT / "trained_agents" / "huri" / "Zerith1-v0_1")
    parser.add_argument("--robots", type=int, default=12)
    parser.add_argument("--steps", type=int, default=200)
    args = parser.parse_args()
    cpu_obs, cpu_fall = rollout("cpu", args.agent, args.robots, args.steps)
    mjx_obs, mjx_fall = rollout("mjx", args.agent, args.robots, args.steps)
    parted = np.abs(cpu_obs - mjx_obs).max(axis=2) > 0.05
    first = [int(np.argmax(row)) if row.any() else -1 for row in parted.T]
    print("robot: kind, level | first fall cpu / mjx | observations part at step")
    for i in range(args.robots):
        kind, level = PAPER_TILE_KINDS[i % len(PAPER_TILE_KINDS)], (i // len(PAPER_TILE_KINDS)) % 3
        falls = " / ".join("-" if f < 0 else str(f) for f in (cpu_fall[i], mjx_fall[i]))
        print(f"{i:3d}: {kind:10s} {level} | {falls:>9s} | {'-' if first[i] < 0 else first[i]}")
    print(
        f"survived {args.steps} steps: cpu {(cpu_fall < 0).sum()}/{args.robots}, "
        f"mjx {(mjx_fall < 0).sum()}/{args.robots}; same first fall: {(cpu_fall == mjx_fall).sum()}"
    )


if __name__ == "__main__":
    main()
