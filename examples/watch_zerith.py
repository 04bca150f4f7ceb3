"""Watch trained Zerith-1 agents walk, record them, and print their survival and velocity tracking.

    python examples/watch_zerith.py                                        # both shipped agents, 0.5 m/s
    python examples/watch_zerith.py trained_agents/huri-baseline/Zerith1-v0_1 --vx 1.0
    python examples/watch_zerith.py --scenario sudden-centroid --episodes 5
    MUJOCO_GL=egl python examples/watch_zerith.py --video videos/       # headless: an mp4 per episode
    python examples/watch_zerith.py --render                               # a MuJoCo window

By default both shipped agents run, one after the other: HuRi (`trained_agents/huri/Zerith1-v0_1`) and the
PPO baseline (`trained_agents/huri-baseline/Zerith1-v0_1`); both walk at the 0.5 m/s command
(docs/training.md).
An agent is a run folder in RL Zoo's layout (as written by `examples/train_zerith.py` or `rl_zoo3 train`):
`Zerith1-v0.zip` and `Zerith1-v0/vecnormalize.pkl`. The policy is deterministic (and `nominal` randomizes
nothing, so its episodes are all the same). Each episode prints its length, whether the robot fell, its
mean forward velocity and its mean forward-velocity error.
`benchmarks/eval_agents.py` evaluates agents on many episodes and every scenario.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import gymnasium as gym
import numpy as np
import torch as th

import zerith_gym
from sb3_huri.zoo import load_run
from zerith_gym.observations import CRITIC_LAYOUT, critic_in_units, layout_slices

ENV_ID = "Zerith1-v0"
SHIPPED = Path(__file__).resolve().parent.parent / "trained_agents"
DEFAULT_AGENTS = [SHIPPED / "huri" / f"{ENV_ID}_1", SHIPPED / "huri-baseline" / f"{ENV_ID}_1"]
_BASE_VELOCITY = layout_slices(CRITIC_LAYOUT)["base_linear_velocity"]


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument(
        "agents", type=Path, nargs="*", default=DEFAULT_AGENTS, help="run folders (default: the shipped ones)"
    )
    parser.add_argument("--scenario", default="nominal", choices=list(zerith_gym.SCENARIOS))
    parser.add_argument(
        "--vx", type=float, default=None, help="forward command (m/s); default: 0.5 on nominal"
    )
    parser.add_argument("--episodes", type=int, default=3)
    parser.add_argument("--seed", type=int, default=0)
    output = parser.add_mutually_exclusive_group()
    output.add_argument(
        "--video", type=Path, default=None, help="folder for an mp4 per episode, a subfolder per method"
    )
    output.add_argument("--render", action="store_true", help="open a MuJoCo viewer window")
    args = parser.parse_args()
    th.set_num_threads(1)

    vx = args.vx if args.vx is not None else (0.5 if args.scenario in ("train", "nominal") else None)
    command = None if vx is None else (vx, 0.0, 0.0)
    for agent in args.agents:
        model_path = agent / f"{ENV_ID}.zip"
        if not model_path.is_file():
            parser.error(f"{model_path} not found: an agent is a run folder holding {ENV_ID}.zip")
        watch(agent, command, args)


def watch(agent: Path, command: tuple[float, float, float] | None, args: argparse.Namespace) -> None:
    """Run one agent for ``args.episodes`` episodes and print what it did."""
    render_mode = "human" if args.render else "rgb_array" if args.video else None
    env = gym.make(ENV_ID, scenario=args.scenario, command=command, render_mode=render_mode)
    if args.video:
        env = gym.wrappers.RecordVideo(
            env,
            str(args.video / agent.parent.name),
            name_prefix=args.scenario,
            episode_trigger=lambda _: True,
            disable_logger=True,
        )
    model, normalizer = load_run(agent, ENV_ID)

    print(f"agent {agent} ({model.method}), scenario {args.scenario}")
    survived = 0
    for episode in range(args.episodes):
        obs, info = env.reset(seed=args.seed + episode)
        target = info["command"][0]
        velocities, done, fell = [], False, False
        while not done:
            policy_obs = normalizer.normalize_obs(obs) if normalizer is not None else obs
            action, _ = model.predict(policy_obs, deterministic=True)
            obs, _, terminated, truncated, info = env.step(action)
            velocities.append(critic_in_units(obs["critic"])[_BASE_VELOCITY][0])
            fell, done = info["fall"], terminated or truncated
        survived += not fell
        mean_vx = float(np.mean(velocities))
        error = float(np.mean(np.abs(np.asarray(velocities) - target)))
        print(
            f"  episode {episode}: {len(velocities) * 0.02:5.2f} s, {'fell' if fell else 'no fall'}, "
            f"command {target:.2f} m/s, mean vx {mean_vx:.2f} m/s, mean |vx error| {error:.3f} m/s"
        )
    print(f"  {survived}/{args.episodes} episodes without a fall")
    env.close()


if __name__ == "__main__":
    main()
