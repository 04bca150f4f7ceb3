"""Markdown tables and their cells, as the experiment reports write them.

A table is a header line, a separator ``|---|---|`` and one line per row: ``| a | b |``. The reports hold
many tables; building them here keeps every one in the same form and checks that each row has as many
cells as its header has columns (a row that does not would shift its cells under the wrong columns).
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence


def table_row(cells: Sequence[object]) -> str:
    """One line of a table: the cells, each written with ``str``, between pipes."""
    return "| " + " | ".join(str(cell) for cell in cells) + " |"


def table_head(columns: Sequence[str]) -> list[str]:
    """A table's first two lines: the column names and the separator."""
    return [table_row(columns), "|" + "---|" * len(columns)]


def table(header: Sequence[str], rows: Iterable[Sequence[object]]) -> list[str]:
    """The lines of a table of ``header``'s columns and one line per row of ``rows`` (no blank line after);
    ValueError for a row whose number of cells is not the header's."""
    lines = table_head(header)
    for row in rows:
        if len(row) != len(header):
            raise ValueError(f"a table row has {len(row)} cells, its header {len(header)} columns: {row!r}")
        lines.append(table_row(row))
    return lines


def mean_cell(stat: tuple[float, float, int], digits: int = 2) -> str:
    """A mean over seeds with the half width of its 95% interval, from ``statistics.mean_ci``: ``-``
    without values, the mean alone where there is no interval (one seed)."""
    mean, half, n = stat
    if n == 0:
        return "-"
    if not math.isfinite(half):
        return f"{mean:.{digits}f}"
    return f"{mean:.{digits}f} ± {half:.{digits}f}"


def interval_cell(value: float, low: float, high: float, spec: str = ".2f") -> str:
    """A value with its interval, ``value [low, high]``, each number in the format ``spec``."""
    return f"{value:{spec}} [{low:{spec}}, {high:{spec}}]"
