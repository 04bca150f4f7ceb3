"""``python -m sb3_huri.zoo train|enjoy|record [RL Zoo arguments]``: RL Zoo's scripts with HuRi registered.

Works whether or not the start-up hook is installed (e.g. with ``pip install --no-deps --target``, frozen
environments, or ``python -S``-like set-ups): it registers HuRi itself and then hands the remaining arguments
to ``rl_zoo3 train``, ``rl_zoo3 enjoy`` or ``python -m rl_zoo3.record_video`` unchanged.
"""

from __future__ import annotations

import runpy
import sys

from sb3_huri.zoo import register

USAGE = "usage: python -m sb3_huri.zoo {train,enjoy,record} [RL Zoo arguments, see <command> --help]"


def main(argv: list[str]) -> None:
    """Run the RL Zoo script named by ``argv[0]`` with the rest of ``argv`` as its arguments."""
    if argv[:1] in (["-h"], ["--help"]):
        print(USAGE)
        return
    if not argv or argv[0] not in ("train", "enjoy", "record"):
        sys.exit(f"{USAGE}\nerror: expected a command, got {' '.join(argv[:1]) or 'nothing'}")
    command, arguments = argv[0], argv[1:]
    register()
    sys.argv = [f"python -m sb3_huri.zoo {command}", *arguments]
    if command == "train":
        from rl_zoo3.train import train

        train()
    elif command == "enjoy":
        from rl_zoo3.enjoy import enjoy

        enjoy()
    else:
        runpy.run_module("rl_zoo3.record_video", run_name="__main__", alter_sys=True)


if __name__ == "__main__":
    main(sys.argv[1:])
