"""Re-evaluate trained Zerith-1 agents: survival, velocity tracking and gait, per scenario.

    python -m study.scripts.eval_agents                                   # the shipped agents, all scenarios
    python -m study.scripts.eval_agents --agents logs/huri/Zerith1-v0_3 --cases nominal@0.5 nominal@1.0
    python -m study.scripts.eval_agents --episodes 50 --seed 1 --json results.json
    python -m study.scripts.eval_agents --backend mjx --solver-iterations 4 --ls-iterations 8  # on MJX

An agent is a run folder in RL Zoo's layout (`Zerith1-v0.zip`, `Zerith1-v0/vecnormalize.pkl`). A case is
`scenario@vx` (command (vx, 0, 0)) or a scenario alone (its own command: (1, 0, 0) for the paper's test
scenarios). Each case runs `--episodes` robots side by side for one 20-s episode each, with the
deterministic policy; robot i is seeded with `seed + i`, so every agent meets the same conditions.

Columns:
- `survive`: share of episodes that reach 20 s without a fall; `low` and `high`: its 95% Wilson interval
  (over `--episodes`: 20 robots know a share to about +-0.2, 100 to about +-0.1);
- `vx_err`: mean |v_x - v_x,cmd| (m/s, pelvis frame) over every step of every episode, up to a fall;
- `vx`: mean forward velocity (m/s); `lin_err`: mean |v_xy - v_xy,cmd|; `yaw_err`: mean |w_z - w_z,cmd|;
- `steps/s`: steps per second, a step being a foot off the ground for at least 60 ms (a walk at the
  0.7-s gait clock makes about 2.9);
- `alt`: share of consecutive steps made by alternate feet, not together (1 = the feet take turns);
- `1-supp`: share of the time on exactly one foot.

The evaluation itself is `sb3_huri.runner.evaluation` (also used by `python -m sb3_huri.experiments`);
`study.analyses.agents.evaluate_agents` runs it over agents and cases.
"""

from __future__ import annotations

import argparse
import json
from dataclasses import asdict
from pathlib import Path

import torch as th

from study.analyses.agents import evaluate_agents
from zerith_gym import ZERITH1_ID
from zerith_gym.core.scenarios import SCENARIOS

ROOT = Path(__file__).resolve().parent.parent
SHIPPED = (
    ROOT / "trained_agents" / "huri" / f"{ZERITH1_ID}_1",
    ROOT / "trained_agents" / "huri-baseline" / f"{ZERITH1_ID}_1",
)
DEFAULT_CASES = (
    "nominal@0.5",
    "nominal@1.0",
    "train@0.5",
    *(
        name
        for name in SCENARIOS
        if name not in ("train", "nominal", "robust", "terrain") and not name.startswith("quadruped-")
    ),
)
"""The plane at two speeds, Zerith-1's training scenario, and every test scenario of Zerith-1 (not the
quadruped's training conditions)."""


def main() -> None:
    """Parse the command line, evaluate every agent on every case, and write the JSON file if asked."""
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--agents", type=Path, nargs="+", default=list(SHIPPED), help="run folders")
    parser.add_argument("--cases", nargs="+", default=list(DEFAULT_CASES), help="scenario or scenario@vx")
    parser.add_argument("--episodes", type=int, default=20)
    parser.add_argument("--seed", type=int, default=1000)
    parser.add_argument("--json", type=Path, default=None, help="also write the results here")
    parser.add_argument("--backend", choices=("cpu", "mjx"), default="cpu", help="the env's simulator")
    parser.add_argument(
        "--solver-iterations", type=int, default=None, help="mjx: constraint solver iterations"
    )
    parser.add_argument("--ls-iterations", type=int, default=None, help="mjx: line-search iterations")
    args = parser.parse_args()
    th.set_num_threads(1)
    backend: dict[str, object] = {"backend": args.backend}
    if args.backend == "mjx":
        backend |= {"solver_iterations": args.solver_iterations, "ls_iterations": args.ls_iterations}
    try:
        results = evaluate_agents(args.agents, args.cases, args.episodes, args.seed, backend)
    except ValueError as error:
        parser.error(str(error))
    if args.json is not None:
        args.json.write_text(json.dumps([asdict(r) for r in results], indent=1))


if __name__ == "__main__":
    main()
