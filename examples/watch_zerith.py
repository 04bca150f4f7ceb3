"""Watch trained agents walk, record them, and print their survival and velocity tracking.

    python examples/watch_zerith.py                                        # the shipped agents, 0.5 m/s
    python examples/watch_zerith.py trained_agents/huri-baseline/Zerith1-v0_1 --vx 1.0
    python examples/watch_zerith.py trained_agents/huri/Go2Like-v0_1 --vx 1.0  # the quadruped
    python examples/watch_zerith.py --scenario sudden-centroid --episodes 5
    MUJOCO_GL=egl python examples/watch_zerith.py --video videos/       # headless: an mp4 per episode
    python examples/watch_zerith.py --render                               # a MuJoCo window

By default the shipped agents run, one after the other: Zerith-1's HuRi (`trained_agents/huri/Zerith1-v0_1`)
and PPO baseline (`trained_agents/huri-baseline/Zerith1-v0_1`), both walking at the 0.5 m/s command
(docs/training.md), then the quadruped's HuRi agent (`trained_agents/huri/Go2Like-v0_1`, trained on terrains,
docs/go2like.md).
An agent is a run folder in RL Zoo's layout (as written by `examples/train_zerith.py` or `rl_zoo3 train`):
`<env id>.zip` and `<env id>/vecnormalize.pkl`, the env id `Zerith1-v0` or `Go2Like-v0`. The policy is
deterministic (and `nominal` randomizes nothing, so its episodes are all the same). Each episode prints its
length, whether the robot fell, its mean forward velocity and its mean forward-velocity error.
`study/scripts/eval_agents.py` evaluates agents on many episodes and every scenario.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import gymnasium as gym
import numpy as np
import torch as th

import zerith_gym
from sb3_huri.runner.folder import load_run
from zerith_gym import ROBOT_ENTRY_POINTS
from zerith_gym.core.observations import layout_slices

ENV_IDS = tuple(env_id for env_id, spec in gym.registry.items() if spec.entry_point in ROBOT_ENTRY_POINTS)
"""The envs whose agents this script can watch: every registered robot env (Zerith1-v0, Go2Like-v0)."""
SHIPPED = Path(__file__).resolve().parent.parent / "trained_agents"
DEFAULT_AGENTS = [
    SHIPPED / "huri" / "Zerith1-v0_1",
    SHIPPED / "huri-baseline" / "Zerith1-v0_1",
    SHIPPED / "huri" / "Go2Like-v0_1",
]


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
    agents = [(agent, env_id_of(agent)) for agent in args.agents]
    for agent, env_id in agents:
        if env_id is None:
            parser.error(
                f"{agent} holds no agent: a run folder holds <env id>.zip, the env id one of "
                + ", ".join(ENV_IDS)
            )
    for agent, env_id in agents:
        watch(agent, env_id, command, args)


def env_id_of(agent: Path) -> str | None:
    """The env the run folder's agent was trained on (the name of its model file), None if it has none."""
    return next((env_id for env_id in ENV_IDS if (agent / f"{env_id}.zip").is_file()), None)


def watch(
    agent: Path, env_id: str, command: tuple[float, float, float] | None, args: argparse.Namespace
) -> None:
    """Run one agent for ``args.episodes`` episodes and print what it did."""
    render_mode = "human" if args.render else "rgb_array" if args.video else None
    env = gym.make(env_id, scenario=args.scenario, command=command, render_mode=render_mode)
    task = env.unwrapped.options.task  # the robot's critic layout and scales
    base_velocity = layout_slices(task.critic_layout)["base_linear_velocity"]
    if args.video:
        env = gym.wrappers.RecordVideo(
            env,
            str(args.video / f"{agent.parent.name}-{env_id}"),
            name_prefix=args.scenario,
            episode_trigger=lambda _: True,
            disable_logger=True,
        )
    model, normalizer = load_run(agent, env_id)

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
            velocities.append(task.critic_in_units(obs["critic"])[base_velocity][0])
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
