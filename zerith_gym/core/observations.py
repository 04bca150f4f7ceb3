"""What every robot's observations share: layouts of named blocks, and the critic's units.

A layout is a sequence of (name, size) blocks; `layout_slices` turns it into index ranges, which each robot's
task and the documentation tables read, so code and docs agree. A critic observation comes out of the env
scaled by known ranges (each robot's `CRITIC_OFFSET`, `CRITIC_SCALE`): forces by `MAX_EXTERNAL_FORCE`,
heights by `HEIGHT_SCALE`.
"""

from __future__ import annotations

MAX_EXTERNAL_FORCE = 200.0
"""The largest external force (N) of the paper's tests (sudden U[150, 200] N): the critic's unit of force."""
HEIGHT_SCALE = 5.0
"""Factor on heights (m) in the critic: 0.2 m to 1."""


def layout_slices(layout: tuple[tuple[str, int], ...]) -> dict[str, slice]:
    """Index range of each block of `layout`."""
    slices, start = {}, 0
    for name, size in layout:
        slices[name] = slice(start, start + size)
        start += size
    return slices
