"""Which reading of the expectation loss (eq. 5) lets the critic fit the spread of a known distribution.

Free atoms (no network) are fitted by Adam to target atoms drawn from a known normal distribution, with the
critic's loss ``energy_distance + coef * expectation_loss`` at a fixed Wang ``beta``, and compared with the
true mean and standard deviation. The ``"distorted"`` reading (eq. 5 as printed: the predicted mean against
its own distorted mean) is zero only for a point mass, so it shrinks the fitted spread as ``beta`` and the
coefficient grow; the ``"target"`` reading (the predicted mean against the target atoms' mean) does not.

    python -m study.scripts.expectation_loss   # table: reading, beta, coef -> fitted std / true std

The fit is `study.analyses.expectation_fit`.
"""

from __future__ import annotations

import argparse

import torch as th

from study.analyses.expectation_fit import KNOWN_MEAN, KNOWN_STD, spread_table


def main() -> None:
    """Parse the command line and print the fitted spread per reading, beta and coefficient."""
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--betas", type=float, nargs="*", default=[0.0, 1.0, 2.0])
    parser.add_argument("--coefs", type=float, nargs="*", default=[0.05, 0.5])
    parser.add_argument("--seeds", type=int, default=3)
    args = parser.parse_args()
    th.set_num_threads(1)
    print(
        f"known distribution N({KNOWN_MEAN}, {KNOWN_STD}^2): fitted std / true std and fitted mean, "
        f"averaged over {args.seeds} seeds"
    )
    for line in spread_table(args.betas, args.coefs, args.seeds):
        print(line, flush=True)


if __name__ == "__main__":
    main()
