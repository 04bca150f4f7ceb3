"""How far a HuRi agent's risk distortion moves the advantages its actor learns from.

    python -m study.scripts.advantages runs/huri/Zerith1-v0_6              # its final evaluation's checkpoint
    python -m study.scripts.advantages runs/huri/Zerith1-v0_6 runs/paper-protocol/huri/Zerith1-v0_1
    python -m study.scripts.advantages runs/huri/Zerith1-v0_7 --steps 30000000 --rollouts 4 --warmup 2

An agent is a run folder of the campaign (RL Zoo's layout, with its `config.yml` and `state.json`). Without
`--steps` the checkpoint is the one of the run's newest final evaluation if the run still holds it, else its
newest model. The run's training env is rebuilt in this process (its preset, the checkpoint's normalizer,
its curriculum: the saved stage for the newest model, the schedule's for a kept checkpoint); the
algorithm's own loop collects `--warmup` rollouts, then `--rollouts` measured ones (robot i seeded `--seed` +
i, stochastic actions as in training; by default each about one episode, so that the robots' episodes are
under way and every phase of them is measured). Each measured rollout's advantages are held against those
of the same rollout under one risk level for all states: the neutral one (Wang beta = 0, CVaR alpha = 1)
and the rollout's mean. Printed: the risk level's mean and spread over the states, and against each level
the correlation, the share of sign changes and that share weighted by the advantage's size, as means over
the rollouts with their range.

Results go to `<run>/evaluations/<steps>-advantages.json`. The work is done by
`study.analyses.advantages`; the results page (advantages section) shows the files.
"""

from __future__ import annotations

from study.analyses.advantages import DEFAULT_SEED, advantages_text, measure_advantages
from study.analyses.command_line import measure_runs, runs_parser


def main() -> None:
    """Parse and check the command line, measure every run folder, and print each one's means."""
    parser = runs_parser(__doc__, DEFAULT_SEED)
    help_default = "(default: as many as one episode takes)"
    parser.add_argument("--warmup", type=int, default=None, help=f"rollouts collected first {help_default}")
    parser.add_argument("--rollouts", type=int, default=None, help=f"rollouts measured {help_default}")
    args = parser.parse_args()
    if (args.warmup is not None and args.warmup < 0) or (args.rollouts is not None and args.rollouts < 1):
        parser.error("--warmup must be at least 0 and --rollouts at least 1")
    options = dict(steps=args.steps, seed=args.seed, warmup=args.warmup, rollouts=args.rollouts)
    measure_runs(parser, args.runs, lambda run: measure_advantages(run, **options), advantages_text)


if __name__ == "__main__":
    main()
