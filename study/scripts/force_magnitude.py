"""Survival over the force's magnitude: every evaluated Zerith-1 agent of the campaign in each Table-1 case
and Fig. 4's load, friction and load-friction cases, the disturbance scaled from 0.1x to 1.5x of the paper's.

    python -m study.scripts.force_magnitude                    # every evaluated agent of runs/campaign.yml
    python -m study.scripts.force_magnitude --report           # what the files hold: curves and 50% scales
    python -m study.scripts.force_magnitude --agents robust-huri-s0-pair --readings test:per-body:hold1
    python -m study.scripts.force_magnitude --robots 20 --scales 0.5 1 1.5

An agent is a queue entry of env Zerith1-v0 with a final evaluation (`<run>/evaluations/<steps>.json`),
measured at the evaluated step (its run's model at that step, a kept checkpoint, or the model committed with
the run's state at that step; else the nearest model held, which the file records). Without `--readings`:
the headline reading (Table 5's test ranges, one force per pair of hands / feet, 0.1-s pushes: the env's
default) for every agent at every `--scales`; for the agents of a HuRi-PPO pair also a force per hand / foot
and 0.02-s pushes (`test:per-body:hold5`, `test:pair:hold1`, `test:per-body:hold1`), and on the nominal
robot at 1x both force readings (`nominal:pair:hold5`, `nominal:per-body:hold5`, Table-1 cases). Each case
and scale runs `--robots` robots (robot i seeded `--seed` + i, the same robots for every agent) for one
20-s episode with the deterministic policy.

Results go to `<run>/evaluations/<steps>-force_magnitude.json` after each case and scale; a second call
skips what is done. The work is done by `study.analyses.force_magnitude` (its docstring says
how each case is scaled); the results page's force-magnitude section shows the files.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import torch as th

from sb3_huri.runner.evaluation import TABLE1_SCENARIOS
from sb3_huri.runner.files import RunError
from study.analyses.force_magnitude import (
    CASES,
    DEFAULT_ROBOTS,
    DEFAULT_SEED,
    HEADLINE,
    NOMINAL_READINGS,
    PAPER_SCALE,
    READINGS,
    SCALES,
    Reading,
    agent_record,
    measure_agent,
    report,
)
from study.results.evaluations import campaign_agents


def main() -> None:
    """Parse and check the command line, then measure (or report) every selected agent."""
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--queue", type=Path, default=Path("runs/campaign.yml"), help="the campaign's queue")
    parser.add_argument("--agents", nargs="+", default=None, help="entry names (default: every one)")
    parser.add_argument("--readings", nargs="+", default=None, help="e.g. test:per-body:hold5")
    parser.add_argument("--scales", type=float, nargs="+", default=list(SCALES))
    parser.add_argument("--robots", type=int, default=DEFAULT_ROBOTS, help="robots per case and scale")
    parser.add_argument("--seed", type=int, default=DEFAULT_SEED, help="robot i is seeded seed + i")
    parser.add_argument("--report", action="store_true", help="print what the files hold, measure nothing")
    args = parser.parse_args()
    if args.robots < 1:
        parser.error("--robots must be at least 1")
    if any(scale <= 0 for scale in args.scales):
        parser.error("--scales must be positive")
    try:
        readings = [Reading.parse(key) for key in args.readings] if args.readings else None
    except ValueError as error:
        parser.error(str(error))
    agents = campaign_agents(args.queue)
    if args.agents:
        unknown = set(args.agents) - {name for agent in agents for name in agent.names}
        if unknown:
            parser.error(f"no evaluated Zerith-1 entry named {', '.join(sorted(unknown))}")
        agents = [agent for agent in agents if set(agent.names) & set(args.agents)]
    if args.report:
        found = [(", ".join(a.names), agent_record(a.run, a.steps)) for a in agents]
        for reading in readings or [HEADLINE]:
            print(report([(name, record) for name, record in found if record is not None], reading) + "\n")
        return
    th.set_num_threads(1)
    began = time.process_time()
    plan = []  # (agent, readings, cases, scales), in the order they run: the headline first
    for agent in agents:
        plan.append((agent, readings or [HEADLINE], CASES, args.scales))
    if readings is None:
        paired = [agent for agent in agents if agent.paired]
        plan += [(agent, READINGS, CASES, args.scales) for agent in paired]
        plan += [(agent, NOMINAL_READINGS, TABLE1_SCENARIOS, [PAPER_SCALE]) for agent in paired]
    for agent, wanted, cases, scales in plan:
        print(f"\n{', '.join(agent.names)}: {', '.join(r.key for r in wanted)}", flush=True)
        try:
            measure_agent(
                agent.run, agent.steps, wanted, cases=cases, scales=scales, robots=args.robots, seed=args.seed
            )
        except RunError as error:
            parser.exit(1, f"{error}\n")
    print(f"\n{time.process_time() - began:.0f} s of CPU time in this process", flush=True)


if __name__ == "__main__":
    main()
