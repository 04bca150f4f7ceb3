"""Re-evaluate trained Zerith-1 agents: survival, velocity tracking and gait, per scenario.

    python benchmarks/eval_agents.py                                   # the shipped agents, all scenarios
    python benchmarks/eval_agents.py --agents logs/huri/Zerith1-v0_3 --cases nominal@0.5 nominal@1.0
    python benchmarks/eval_agents.py --episodes 50 --seed 1 --json results.json

An agent is a run folder in RL Zoo's layout (`Zerith1-v0.zip`, `Zerith1-v0/vecnormalize.pkl`). A case is
`scenario@vx` (command (vx, 0, 0)) or a scenario alone (its own command: (1, 0, 0) for the paper's test
scenarios). Each case runs `--episodes` robots side by side for one 20-s episode each, with the
deterministic policy; robot i is seeded with `seed + i`, so every agent meets the same conditions.

Columns:
- `survive`: share of episodes that reach 20 s without a fall;
- `vx_err`: mean |v_x - v_x,cmd| (m/s, pelvis frame) over every step of every episode, up to a fall;
- `vx`: mean forward velocity (m/s); `lin_err`: mean |v_xy - v_xy,cmd|; `yaw_err`: mean |w_z - w_z,cmd|;
- `steps/s`: steps per second, a step being a foot off the ground for at least 60 ms (a walk at the
  0.7-s gait clock makes about 2.9);
- `alt`: share of consecutive steps made by alternate feet, not together (1 = the feet take turns);
- `1-supp`: share of the time on exactly one foot.
"""

from __future__ import annotations

import argparse
import itertools
import json
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np
import torch as th
from stable_baselines3.common.vec_env import VecNormalize

import zerith_gym
from sb3_huri import HuRiPPO
from sb3_huri.zoo import load_run
from zerith_gym.observations import CRITIC_LAYOUT, layout_slices
from zerith_gym.robot import CONTROL_DT
from zerith_gym.scenarios import SCENARIOS

ENV_ID = "Zerith1-v0"
ROOT = Path(__file__).resolve().parent.parent
SHIPPED = (
    ROOT / "trained_agents" / "huri" / f"{ENV_ID}_1",
    ROOT / "trained_agents" / "ppo" / f"{ENV_ID}_1",
)
DEFAULT_CASES = (
    "nominal@0.5",
    "nominal@1.0",
    "train@0.5",
    *(name for name in SCENARIOS if name not in ("train", "nominal")),
)
_CRITIC = layout_slices(CRITIC_LAYOUT)
MIN_AIR_STEPS = 3
"""A foot must stay off the ground this many control steps (60 ms) for a step to count."""


@dataclass
class CaseResult:
    agent: str
    case: str
    episodes: int
    survive: float
    vx_err: float
    vx: float
    lin_err: float
    yaw_err: float
    steps_per_s: float
    alternation: float
    single_support: float


def parse_case(case: str) -> tuple[str, tuple[float, float, float] | None]:
    """`scenario@vx` -> (scenario, (vx, 0, 0)); `scenario` -> (scenario, None)."""
    name, _, vx = case.partition("@")
    if name not in SCENARIOS:
        raise ValueError(
            f"unknown scenario {name!r} in case {case!r}; valid scenarios: {', '.join(SCENARIOS)}"
        )
    return name, None if not vx else (float(vx), 0.0, 0.0)


def gait_measures(contact: np.ndarray, min_air_steps: int = MIN_AIR_STEPS) -> tuple[float, float, float]:
    """Steps per second, share of consecutive steps taken in turn by the two feet, single-support share.

    `contact` is (steps, 2) booleans of one episode; a step is a foot leaving the ground for at least
    `min_air_steps` control steps (shorter losses of contact are chatter, not steps).
    """
    starts = []
    for foot in range(2):
        air = np.concatenate([[False], ~contact[:, foot], [False]]).astype(np.int8)
        edges = np.diff(air)
        lift, land = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)
        real = lift[land - lift >= min_air_steps]
        starts.append(real)
    # A step alternates when the other foot stepped exactly once since this foot's previous step, and
    # not together with it (which would be a two-footed hop).
    turns = []
    for own, other in ((starts[0], starts[1]), (starts[1], starts[0])):
        for previous, current in itertools.pairwise(own):
            between = other[(other > previous) & (other < current)]
            together = np.abs(other - current).min(initial=min_air_steps) < min_air_steps
            turns.append(len(between) == 1 and not together)
    alternation = float(np.mean(turns)) if turns else 0.0
    steps = sum(len(own) for own in starts)
    rate = steps / (len(contact) * CONTROL_DT)
    single = float(np.mean(contact.sum(axis=1) == 1))
    return rate, alternation, single


def evaluate(
    model: HuRiPPO,
    normalizer: VecNormalize | None,
    scenario: str,
    command: tuple[float, float, float] | None,
    episodes: int,
    seed: int,
) -> dict[str, float]:
    """Run one episode on each of `episodes` robots and summarize them (see the module docstring)."""
    env = zerith_gym.make_vec_env(episodes, seed=seed, scenario=scenario, command=command)
    obs = env.reset()
    horizon = env.options.episode_steps
    vx_cmd = np.array([info["command"][0] for info in env.reset_infos])
    alive = np.ones(episodes, dtype=bool)
    fell = np.zeros(episodes, dtype=bool)
    vx = np.full((horizon, episodes), np.nan)
    lin_err, yaw_err = np.full_like(vx, np.nan), np.full_like(vx, np.nan)
    contact = np.zeros((horizon, episodes, 2), dtype=bool)
    for t in range(horizon):
        policy_obs = normalizer.normalize_obs(obs) if normalizer is not None else obs
        action, _ = model.predict(policy_obs, deterministic=True)
        obs, _, dones, infos = env.step(action)
        critic = np.stack(
            [
                info.get("terminal_observation", obs)["critic"] if d else obs["critic"][i]
                for i, (info, d) in enumerate(zip(infos, dones, strict=True))
            ]
        )
        vx[t, alive] = critic[alive, _CRITIC["base_linear_velocity"]][:, 0]
        contact[t, alive] = critic[alive, _CRITIC["foot_contact"]] > 0.5
        lin_err[t, alive] = [infos[i]["lin_vel_error"] for i in np.flatnonzero(alive)]
        yaw_err[t, alive] = [infos[i]["ang_vel_error"] for i in np.flatnonzero(alive)]
        fell |= alive & np.array([info["fall"] for info in infos])
        alive &= ~dones
        if not alive.any():
            break
    gait = np.array([gait_measures(contact[~np.isnan(vx[:, i]), i]) for i in range(episodes)])
    return {
        "survive": float(np.mean(~fell)),
        "vx_err": float(np.nanmean(np.abs(vx - vx_cmd))),
        "vx": float(np.nanmean(vx)),
        "lin_err": float(np.nanmean(lin_err)),
        "yaw_err": float(np.nanmean(yaw_err)),
        "steps_per_s": float(gait[:, 0].mean()),
        "alternation": float(gait[:, 1].mean()),
        "single_support": float(gait[:, 2].mean()),
    }


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--agents", type=Path, nargs="+", default=list(SHIPPED), help="run folders")
    parser.add_argument("--cases", nargs="+", default=list(DEFAULT_CASES), help="scenario or scenario@vx")
    parser.add_argument("--episodes", type=int, default=20)
    parser.add_argument("--seed", type=int, default=1000)
    parser.add_argument("--json", type=Path, default=None, help="also write the results here")
    args = parser.parse_args()
    th.set_num_threads(1)
    cases = [(case, *parse_case(case)) for case in args.cases]

    results: list[CaseResult] = []
    columns = ("survive", "vx_err", "vx", "lin_err", "yaw_err", "steps/s", "alt", "1-supp")
    print(f"{'agent':<28} {'case':<22} " + " ".join(f"{c:>7}" for c in columns))
    for folder in args.agents:
        model, normalizer = load_run(folder, ENV_ID)
        agent = f"{folder.parent.name}/{folder.name}"
        for case, scenario, command in cases:
            metrics = evaluate(model, normalizer, scenario, command, args.episodes, args.seed)
            results.append(CaseResult(agent, case, args.episodes, **metrics))
            print(f"{agent:<28} {case:<22} " + " ".join(f"{v:>7.3f}" for v in metrics.values()), flush=True)
    if args.json is not None:
        args.json.write_text(json.dumps([asdict(r) for r in results], indent=1))


if __name__ == "__main__":
    main()
