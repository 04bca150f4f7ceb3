"""Markdown pieces of the results page: step counts, links, figures, shares, differences (its tables:
``sb3_huri.experiments.markdown``)."""

from __future__ import annotations

import io
import math
import os
from pathlib import Path
from typing import Any

from sb3_huri.experiments.markdown import interval_cell
from sb3_huri.experiments.statistics import wilson_interval


def millions(steps: int) -> str:
    """Steps in millions, as the page's labels write them."""
    return f"{steps / 1e6:.1f}M"


def link(path: Path, page: Path) -> str:
    """``path`` relative to the page's folder (a link that works from the page)."""
    return os.path.relpath(path, page.parent)


def save_figure(figure: Any, path: Path, dpi: int) -> None:
    """Write a matplotlib figure as a PNG without the matplotlib version in it, and only where its bytes
    differ from the file there: a figure of unchanged data stays the same file (no change for git)."""
    buffer = io.BytesIO()
    figure.savefig(buffer, format="png", dpi=dpi, metadata={"Software": None})
    content = buffer.getvalue()
    if path.is_file() and path.read_bytes() == content:
        return
    path.write_bytes(content)


def figure_lines(path: Path, page: Path, drawn: bool = True) -> list[str]:
    """The page's lines showing a figure just drawn; a figure not drawn this time is deleted, so that no
    figure outlives the data it was drawn from."""
    if not drawn:
        path.unlink(missing_ok=True)
        return []
    return [f"![{path.stem}]({link(path, page)})", ""]


def share_cell(share: float, n: int) -> str:
    """A survival share with its 95% Wilson interval."""
    if n == 0 or not math.isfinite(share):
        return "-"
    return interval_cell(share, *wilson_interval(share, n))


def difference_cell(value: float, low: float, high: float) -> str:
    """A difference with its 95% interval, signs shown."""
    return interval_cell(value, low, high, "+.3f")


def verdict(low: float, high: float, first: str, second: str) -> str:
    """What a 95% interval of ``first - second`` says, in words."""
    if low <= 0.0 <= high:
        return "the interval includes 0: no difference measured"
    return f"{first if low > 0 else second} survives more"
