"""Which single push an agent survives: survival against the impulse, per force target and direction.

Table 1's sudden cases push every 2 s with U[150, 200] N for 0.1 s, and the same force acts on each body of
the target group: one body for the centroid, two for the hands and the feet, so a hand or foot push carries
twice the impulse of a centroid push. This gives a walking agent one push of 0.1 s, of a fixed force per body,
from one of four directions (world frame; the robot walks along +x), and counts the episodes that end
without a fall within `--after` control steps of the push (default 3 s). What a push does depends on the
gait's phase when it comes (which foot is on the ground), so each cell pushes at `--phases` times spread
over one gait period from 2 s on, `--robots` robots each. The robot is the nominal one (one robot per phase
is then enough: the episodes are deterministic) unless `--test-ranges` (Table 1's load, friction and CoM
ranges). `--stand` gives the same pushes to a robot that holds its default stance (zero action, zero
command): the reference a policy should beat.

Each cell reports the survival share over phases and robots; the header gives the total impulse (N s) and
the velocity change it would give the whole nominal robot (impulse / 36 kg).

`--table1` measures the same in Table 1's own sudden episodes instead: a 20-s episode holds nine pushes
(every 2 s from 2 s on), so its survival is the product of nine per-push survivals. For each sudden case it
runs `--robots` episodes and counts, push by push, the robots standing when it came and those that fell
before the next one: the per-push survival, and the episode survival it compounds to.

    python -m study.scripts.impulse_envelope runs/huri/Zerith1-v0_1
    python -m study.scripts.impulse_envelope runs/huri/Zerith1-v0_1 --stand --forces 25 50 100
    python -m study.scripts.impulse_envelope runs/huri/Zerith1-v0_1 --table1 --robots 100

The work is done by `study.analyses.impulses`.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import torch as th

from sb3_huri.runner.evaluation import HoldStance
from sb3_huri.runner.folder import load_run
from study.analyses.impulses import PUSH_STEPS, print_envelope, print_table1
from zerith_gym import ZERITH1_ID
from zerith_gym.core.disturbances import FORCE_TARGET_NAMES
from zerith_gym.core.scenarios import TEST_COMMAND


def main() -> None:
    """Parse and check the command line, then print the push envelope or Table 1's per-push survival."""
    formatter = argparse.RawDescriptionHelpFormatter
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=formatter)
    parser.add_argument("agent", type=Path, help="a run folder in RL Zoo's layout")
    parser.add_argument("--targets", nargs="+", default=list(FORCE_TARGET_NAMES), choices=FORCE_TARGET_NAMES)
    parser.add_argument("--forces", type=float, nargs="+", default=[100.0, 150.0, 200.0, 250.0, 300.0])
    parser.add_argument("--phases", type=int, default=8, help="push times per cell, over one gait period")
    parser.add_argument("--robots", type=int, default=1, help="episodes per phase; robot i seeded seed + i")
    parser.add_argument("--after", type=int, default=150, help="control steps from the push to the end")
    parser.add_argument("--seed", type=int, default=1000)
    parser.add_argument("--test-ranges", action="store_true", help="Table 1's load, friction and CoM ranges")
    parser.add_argument("--stand", action="store_true", help="zero action and zero command instead")
    parser.add_argument("--table1", action="store_true", help="per-push survival in Table 1's sudden cases")
    args = parser.parse_args()
    if min(args.robots, args.phases) < 1 or args.after <= PUSH_STEPS:
        parser.error(f"need --robots >= 1, --phases >= 1 and --after > {PUSH_STEPS} (the push's length)")
    if any(force <= 0 for force in args.forces):
        parser.error(f"--forces must be positive (N per body), got {args.forces}")
    th.set_num_threads(1)
    model, normalizer = load_run(args.agent, ZERITH1_ID)
    command = TEST_COMMAND
    if args.stand:
        model, normalizer, command = HoldStance(), None, (0.0, 0.0, 0.0)
    if args.table1:
        print_table1(model, normalizer, args.robots, args.seed)
    else:
        print_envelope(
            model, normalizer, command, args.targets, args.forces, args.phases, args.robots, args.after,
            args.seed, args.test_ranges,
        )  # fmt: skip


if __name__ == "__main__":
    main()
