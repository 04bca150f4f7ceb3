"""The risk levels a HuRi agent's critic sets on the states it visits: IQR band shares, beta and beta_RND.

    python -m study.scripts.risk_levels runs/huri/Zerith1-v0_6       # the checkpoint of its final evaluation
    python -m study.scripts.risk_levels runs/huri/Zerith1-v0_6 runs/robust-256/huri/Zerith1-v0_1
    python -m study.scripts.risk_levels runs/huri/Zerith1-v0_7 --steps 156732992  # the first model at/after
    python -m study.scripts.risk_levels runs/huri/Zerith1-v0_6 --cases nominal@1 uneven --robots 20

An agent is a run folder of the campaign (RL Zoo's layout: `Zerith1-v0.zip` or `Go2Like-v0.zip` and its
`vecnormalize.pkl`). Without `--steps` the checkpoint is the one of the run's newest final evaluation if the
run still holds it, else its newest model. Each case runs `--robots` robots (robot i seeded `--seed` + i, the
same robots for every agent) for one 20-s episode with the deterministic policy; every state a robot visits
before its episode ends is read by the critic. Default cases: the plane at 1 m/s, the paper's Fig. 5
conditions (Zerith-1: `sudden-centroid`, `uneven`; the quadruped: `platform-0.40`, `quadruped-rough@1`), the
run's training scenario at 1 m/s and with its own commands, and the plane at 0.5 m/s.

Columns, over the visited states: `below`, `within`, `above`: shares of states whose critic IQR is below,
within or above the agent's own IQR band (its saved thresholds); `beta`, `b_IQR`, `b_RND`: the mean risk
level and its two parts (CVaR: alpha); `RND_p90`: the 90th percentile of beta_RND; `RND>0.5`: the share of
states with beta_RND above 0.5; `IQR_med`: the median IQR; `survive`: robots without a fall.

Results go to `<run>/evaluations/<steps>-risk_levels.json` after each case; a second call skips the cases
done. The work is done by `study.analyses.risk_levels`; the results page (risk-levels section) shows
the files.
"""

from __future__ import annotations

from study.analyses.agents import check_cases
from study.analyses.command_line import measure_runs, runs_parser
from study.analyses.risk_levels import (
    DEFAULT_ROBOTS,
    DEFAULT_SEED,
    measure_risk_levels,
    risk_levels_text,
)


def main() -> None:
    """Parse and check the command line, measure every run folder, and print each one's table."""
    parser = runs_parser(__doc__, DEFAULT_SEED)
    parser.add_argument("--cases", nargs="+", default=None, help="scenario or scenario@vx")
    parser.add_argument("--robots", type=int, default=DEFAULT_ROBOTS, help="robots per case")
    parser.add_argument("--episode-steps", type=int, default=None, help="time limit (default 1000: 20 s)")
    args = parser.parse_args()
    if args.robots < 1:
        parser.error("--robots must be at least 1")
    try:
        check_cases(args.cases or [])
    except ValueError as error:
        parser.error(str(error))
    options = dict(cases=args.cases, robots=args.robots, seed=args.seed, episode_steps=args.episode_steps)
    measure_runs(
        parser, args.runs, lambda run: measure_risk_levels(run, steps=args.steps, **options), risk_levels_text
    )


if __name__ == "__main__":
    main()
