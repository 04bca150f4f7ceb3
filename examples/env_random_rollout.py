"""Zerith1-v0 in a few lines: one episode of random actions, with the reward terms it was paid for.

python examples/env_random_rollout.py [--scenario sudden-centroid]
"""

import argparse

import gymnasium as gym
import numpy as np

import zerith_gym  # registers Zerith1-v0

parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
parser.add_argument("--scenario", default="train", choices=list(zerith_gym.SCENARIOS))
args = parser.parse_args()

env = gym.make("Zerith1-v0", scenario=args.scenario)
obs, info = env.reset(seed=0)
print(f"scenario {args.scenario}: policy obs {obs['policy'].shape}, critic obs {obs['critic'].shape}")
print(f"command (vx, vy, yaw rate): {np.round(info['command'], 2)}")

episode_return, steps = 0.0, 0
while True:
    obs, reward, terminated, truncated, info = env.step(env.action_space.sample())
    episode_return += reward
    steps += 1
    if terminated or truncated:
        break

ending = "fell" if info["fall"] else "unstable simulation" if info["sim_unstable"] else "time limit"
print(f"{steps} steps ({steps * 0.02:.2f} s), return {episode_return:.3f}, ended by: {ending}")
for name, value in sorted(info["episode_terms"].items(), key=lambda item: -abs(item[1]))[:8]:
    print(f"  {name:22s} {value:+.4f}")
env.close()
