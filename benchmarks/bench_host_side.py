"""The host side of a ZerithVecEnv step at thousands of robots, without the physics.

What every step costs in Python beside the simulation, whatever the backend: the episode bookkeeping and
info dicts of `ZerithVecEnv.step_wait`, then what SB3 and the preset's callbacks read of them each step
(SB3's episode buffer and time-limit bootstrap, `RewardTermsLogger`, `RunCheckpoint`). The robots are
replaced by one precomputed step of `--robots` robots (1% of them ending), so the figure is the host cost
alone, as on a GPU where the jitted MJX step itself takes a few milliseconds.

    python benchmarks/bench_host_side.py --robots 4096 16384
"""

from __future__ import annotations

import argparse
import time

import numpy as np

import zerith_gym
from zerith_gym.core.contract import BatchStep
from zerith_gym.core.task import StepOutput
from zerith_gym.sb3.callbacks import RewardTermsLogger
from zerith_gym.zerith1 import constants as robot
from zerith_gym.zerith1.observations import CRITIC_SIZE, POLICY_SIZE
from zerith_gym.zerith1.rewards import REWARD_NAMES


class PrecomputedRobots:
    """Stands in for the robots: every step returns the same `BatchStep` of n robots."""

    def __init__(self, n: int, ended_share: float = 0.01) -> None:
        rng = np.random.default_rng(0)
        ended = rng.random(n) < ended_share
        out = StepOutput(
            policy_obs=rng.normal(size=(n, POLICY_SIZE)).astype(np.float32),
            critic_obs=rng.normal(size=(n, CRITIC_SIZE)).astype(np.float32),
            reward=rng.normal(size=n),
            terminated=ended & (rng.random(n) < 0.5),
            truncated=ended & (rng.random(n) >= 0.5),
            fall=ended & (rng.random(n) < 0.5),
            sim_unstable=np.zeros(n, dtype=bool),
            lin_vel_error=rng.random(n),
            ang_vel_error=rng.random(n),
            terms=rng.normal(size=(n, len(REWARD_NAMES))),
        )
        force, command, next_command = (rng.normal(size=(n, 3)) for _ in range(3))
        policy, critic = out.policy_obs.copy(), out.critic_obs.copy()
        level = np.zeros(n, dtype=int)
        self.step_result = BatchStep(out, force, command, policy, critic, next_command, level, REWARD_NAMES)

    def step(self, actions: np.ndarray) -> BatchStep:
        return self.step_result

    def close(self) -> None:
        pass


def host_env(n: int) -> zerith_gym.ZerithVecEnv:
    """A ZerithVecEnv of n robots whose robots are `PrecomputedRobots` (its bookkeeping sized for n)."""
    env = zerith_gym.make_vec_env(1, workers=0)
    env.reset()
    env.close()
    env.robots = PrecomputedRobots(n)
    env.num_envs = n
    env._action_shape = (n, robot.NUM_JOINTS)
    env._returns, env._lengths = np.zeros(n), np.zeros(n, dtype=int)
    env._term_sums = np.zeros((n, len(REWARD_NAMES)))
    env.reset_infos = [{} for _ in range(n)]
    return env


def sb3_reads(infos, dones) -> None:
    """What SB3's on-policy loop reads of the infos each step (episode buffer, time-limit bootstrap)."""
    for info in infos:
        info.get("episode")
        info.get("is_success")
    for idx, done in enumerate(dones):
        if (
            done
            and infos[idx].get("terminal_observation") is not None
            and infos[idx].get("TimeLimit.truncated")
        ):
            infos[idx]["terminal_observation"]["policy"]


class _Locals(RewardTermsLogger):
    def read(self, infos, dones) -> None:
        self.locals = {"infos": infos, "dones": dones}
        self._on_step()


def measure(n: int, steps: int) -> dict[str, float]:
    env = host_env(n)
    actions = np.zeros((n, robot.NUM_JOINTS))
    logger = _Locals()
    timings = {"step_wait": 0.0, "sb3": 0.0, "reward_terms_logger": 0.0}
    for _ in range(steps):
        began = time.perf_counter()
        env.step_async(actions)
        _, _, dones, infos = env.step_wait()
        stepped = time.perf_counter()
        sb3_reads(infos, dones)
        read = time.perf_counter()
        logger.read(infos, dones)
        logged = time.perf_counter()
        timings["step_wait"] += stepped - began
        timings["sb3"] += read - stepped
        timings["reward_terms_logger"] += logged - read
    per_step = {key: 1000 * value / steps for key, value in timings.items()}
    return {**per_step, "total": sum(per_step.values())}


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--robots", type=int, nargs="+", default=[4096, 16384])
    parser.add_argument("--steps", type=int, default=20)
    args = parser.parse_args()
    print("robots | step_wait (ms) | SB3's reads (ms) | RewardTermsLogger (ms) | total ms per step")
    for n in args.robots:
        t = measure(n, args.steps)
        print(
            f"{n} | {t['step_wait']:.1f} | {t['sb3']:.1f} | {t['reward_terms_logger']:.1f} | {t['total']:.1f}"
        )


if __name__ == "__main__":
    main()
