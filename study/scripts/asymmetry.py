"""How far an agent's actor is from acting left-right symmetrically, on the observations of its own walk.

Zerith-1 is mirror-symmetric (`zerith_gym.zerith1.symmetry`): a symmetric policy acts on the mirrored
observation as the mirror of its action, and bears a push from the right as it bears one from the left. This
runs the agent's deterministic policy on each case (`scenario` or `scenario@vx`, as
`sb3_huri.runner.evaluation` reads cases) and reports `sb3_huri.common.mirror.mirror_loss` over the visited
observations (the mean squared distance between the action on the mirrored observation and the mirrored
action; 0 is symmetric), next to the mean squared action, the scale it compares with.

    python -m study.scripts.asymmetry runs/huri/Zerith1-v0_1
    python -m study.scripts.asymmetry runs/huri/Zerith1-v0_2 runs/huri/Zerith1-v0_1 --cases nominal@1.0
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

import numpy as np
import torch as th

import zerith_gym
from sb3_huri.common.mirror import NormalizedMirror, mirror_loss
from sb3_huri.runner.evaluation import parse_case
from sb3_huri.runner.folder import load_run
from zerith_gym.zerith1.symmetry import ACTION_MIRROR, POLICY_MIRROR


def asymmetry(
    model: Any, normalizer: Any, case: str, robots: int, steps: int, seed: int
) -> tuple[float, float]:
    """The actor's mirror loss over `robots` x `steps` observations of its walk in `case` (`model` and its
    `normalizer` as `load_run` gives them), and its mean squared action there."""
    stats = normalizer.obs_rms["policy"]
    observation_mirror = NormalizedMirror.build(
        POLICY_MIRROR, stats.mean, np.sqrt(stats.var + normalizer.epsilon)
    )
    scenario, command = parse_case(case)
    env = zerith_gym.make_vec_env(robots, seed=seed, scenario=scenario, command=command, workers=0)
    seen, actions = [], []
    obs = env.reset()
    for _ in range(steps):
        policy_obs = normalizer.normalize_obs(obs)
        action, _ = model.predict(policy_obs, deterministic=True)
        seen.append(policy_obs["policy"])
        actions.append(action)
        obs, *_ = env.step(action)
    env.close()
    observations = th.as_tensor(np.concatenate(seen), dtype=th.float32)
    with th.no_grad():
        loss = mirror_loss(
            model.policy.actor_mean, observations, observation_mirror, NormalizedMirror.build(ACTION_MIRROR)
        )
    return float(loss), float((np.concatenate(actions) ** 2).sum(axis=1).mean())


def main() -> None:
    formatter = argparse.RawDescriptionHelpFormatter
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=formatter)
    parser.add_argument("agents", type=Path, nargs="+", help="run folders in RL Zoo's layout")
    parser.add_argument("--cases", nargs="+", default=["nominal@1.0", "nominal@0.5", "sudden-hands"])
    parser.add_argument("--robots", type=int, default=16)
    parser.add_argument("--steps", type=int, default=300, help="control steps of every robot")
    parser.add_argument("--seed", type=int, default=1000)
    args = parser.parse_args()
    th.set_num_threads(1)
    print("| agent | case | asymmetry (mirror loss) | mean squared action |")
    print("|---|---|---|---|")
    for agent in args.agents:
        model, normalizer = load_run(agent, "Zerith1-v0", normalized=True)
        for case in args.cases:
            loss, scale = asymmetry(model, normalizer, case, args.robots, args.steps, args.seed)
            print(f"| {agent} | {case} | {loss:.3f} | {scale:.3f} |", flush=True)


if __name__ == "__main__":
    main()
