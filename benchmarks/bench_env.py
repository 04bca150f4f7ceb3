"""Single-env speed of Zerith1-v0 against raw MuJoCo physics on the same model, in the same run.

Prints control steps per second of (a) `mj_step(model, data, nstep=decimation)` in a Python loop with
fixed controls (the physics limit of one env), (b) the unwrapped env's `step` and (c) the env from
`gym.make` (with gymnasium's wrappers), random actions, resetting at episode ends, and the ratios.

    python benchmarks/bench_env.py [--steps 20000] [--scenario train]
"""

from __future__ import annotations

import argparse
import time

import gymnasium as gym
import mujoco
import numpy as np

import zerith_gym
from zerith_gym import robot


def physics_rate(env: zerith_gym.Zerith1Env, steps: int) -> float:
    """Control steps/s of raw physics on the env's own model, from the env's reset state."""
    model, data = env.model, env.data
    env.reset(seed=1)
    data.ctrl[:] = robot.DEFAULT_JOINT_POS
    start = time.perf_counter()
    for _ in range(steps):
        mujoco.mj_step(model, data, nstep=robot.DECIMATION)
    return steps / (time.perf_counter() - start)


def env_rate(env: gym.Env, steps: int, seed: int = 0) -> float:
    """Control steps/s of `env.step` with uniform random actions (drawn beforehand), resets included."""
    rng = np.random.default_rng(seed)
    actions = rng.uniform(-1.0, 1.0, size=(steps, robot.NUM_JOINTS)).astype(np.float32)
    env.reset(seed=seed)
    start = time.perf_counter()
    for action in actions:
        _, _, terminated, truncated, _ = env.step(action)
        if terminated or truncated:
            env.reset()
    return steps / (time.perf_counter() - start)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=20000)
    parser.add_argument("--scenario", default="train")
    args = parser.parse_args()

    wrapped = gym.make("Zerith1-v0", scenario=args.scenario)
    env = wrapped.unwrapped
    physics_rate(env, 1000)  # warm-up
    env_rate(wrapped, 1000)
    physics = physics_rate(env, args.steps)
    bare = env_rate(env, args.steps)
    made = env_rate(wrapped, args.steps)
    print(f"scenario {args.scenario}, physics dt {robot.PHYSICS_DT} s x {robot.DECIMATION} per control step")
    print(f"raw mj_step(nstep={robot.DECIMATION}):  {physics:9.0f} control steps/s")
    print(f"Zerith1Env.step (unwrapped):  {bare:9.0f} steps/s   ratio {bare / physics:.2f}")
    print(f"gym.make env.step (wrapped):  {made:9.0f} steps/s   ratio {made / physics:.2f}")


if __name__ == "__main__":
    main()
