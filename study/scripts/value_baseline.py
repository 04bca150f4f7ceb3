"""How good a baseline each agent's value is, and its risk level before a fall, on its training rollouts.

    python -m study.scripts.value_baseline runs/huri/Zerith1-v0_6 runs/huri-baseline/Zerith1-v0_1 \
        --steps 156732992                                    # the robust recipe's seed-0 pair
    python -m study.scripts.value_baseline runs/huri-neutral/Zerith1-v0_1 --rollouts 4

An agent is a run folder of the campaign. Without `--steps` the checkpoint is the one of the run's newest
final evaluation, else its newest model; a checkpoint the run no longer holds is taken from the commit that
holds it. The run's training env is rebuilt in this process (its preset, the checkpoint's normalizer, its
curriculum) and the algorithm's own loop collects `--warmup` rollouts (default: one episode's worth), then
`--rollouts` measured ones (robot i seeded `--seed` + i, stochastic actions as in training). Printed: the
explained variance of the lambda = 1 returns by the value the advantages use (HuRi's V_beta, PPO's V) and
by the critic's atom mean, pooled and per rollout; the mean risk level within 25 steps of a fall and
elsewhere.

Results go to `<run>/evaluations/<steps>-value_baseline.json`. The work is done by
`study.analyses.value_baseline`; the results page shows the files.
"""

from __future__ import annotations

from study.analyses.command_line import measure_runs, runs_parser
from study.analyses.value_baseline import (
    DEFAULT_ROLLOUTS,
    DEFAULT_SEED,
    measure_value_baseline,
    value_baseline_text,
)


def main() -> None:
    """Parse and check the command line, measure every run folder, and print each one's measures."""
    parser = runs_parser(__doc__, DEFAULT_SEED)
    parser.add_argument(
        "--warmup", type=int, default=None, help="rollouts collected first (default: one episode's)"
    )
    parser.add_argument("--rollouts", type=int, default=DEFAULT_ROLLOUTS, help="rollouts measured")
    args = parser.parse_args()
    if (args.warmup is not None and args.warmup < 0) or args.rollouts < 1:
        parser.error("--warmup must be at least 0 and --rollouts at least 1")
    options = dict(steps=args.steps, seed=args.seed, warmup=args.warmup, rollouts=args.rollouts)
    measure_runs(parser, args.runs, lambda run: measure_value_baseline(run, **options), value_baseline_text)


if __name__ == "__main__":
    main()
