"""The README and the docs hold no dead links: every relative link and image path names a file that exists."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
PAGES = sorted([REPO / "README.md", *(REPO / "docs").rglob("*.md")])
LINK = re.compile(r"!?\[[^\]]*\]\(([^)\s]+)\)")
"""A markdown link or image, ``[text](target)``: the target is group 1."""


def relative_targets(page: Path) -> list[str]:
    """The page's link targets that point into the repository (no scheme, no bare anchor)."""
    text = re.sub(r"```.*?```", "", page.read_text(), flags=re.DOTALL)  # commands are not links
    return [t for t in LINK.findall(text) if not re.match(r"[a-z]+:", t) and not t.startswith("#")]


@pytest.mark.parametrize("page", PAGES, ids=lambda p: str(p.relative_to(REPO)))
def test_every_relative_link_names_an_existing_file(page: Path) -> None:
    missing = [t for t in relative_targets(page) if not (page.parent / t.split("#")[0]).exists()]
    assert not missing, f"{page.relative_to(REPO)} links to missing files: {missing}"


def test_the_link_pattern_finds_links_and_images(tmp_path: Path) -> None:
    page = tmp_path / "page.md"
    page.write_text("[a](x.md#part) ![b](media/y.png) [c](https://e.org) [d](#here)\n```\n[e](z.md)\n```\n")
    assert relative_targets(page) == ["x.md#part", "media/y.png"]


def test_the_standard_task_tables_in_docs_are_the_generated_reports() -> None:
    """docs/huri.md's five-seed tables hold every row of `results/mujoco/report.md`'s per-task and
    across-task tables as written by `python -m sb3_huri.experiments report`, so the docs cannot keep old
    numbers."""
    report = (REPO / "results" / "mujoco" / "report.md").read_text()
    docs = (REPO / "docs" / "huri.md").read_text()
    rows = []
    for title in ("HalfCheetah-v5", "Walker2d-v5", "Across tasks"):
        part = report.split(f"\n## {title}\n", 1)[1].split("\n## ", 1)[0]
        rows += [line for line in part.splitlines() if line.startswith("| `")]
    assert len(rows) >= 8, "the report has fewer method rows than its three tables should"
    stale = [row for row in rows if row not in docs]
    assert not stale, f"docs/huri.md lacks these rows of results/mujoco/report.md: {stale}"
