"""The results page's sections in page order: each section's number is given here and nowhere else.

A section's module writes its heading with ``heading(key, title)`` and refers to another section with
``section(key)``; the page (``study.results.write_results``) assembles them in this order. A key with a
leading ``+`` is a sub-section, lettered after the section before it (6, then 6b, 6c, ...).
"""

from __future__ import annotations

PAGE_ORDER = (
    "status",
    "table1",
    "robustness",
    "returns",
    "tracking",
    "risk",
    "+risk_levels",
    "+advantages",
    "+value_baseline",
    "quadruped",
    "rollout_shape",
    "terrains",
    "force_magnitude",
    "band",
)


def _numbers(order: tuple[str, ...]) -> dict[str, str]:
    """Each key's number: 1, 2, ... for sections, the section's number and b, c, ... for its sub-sections."""
    numbers: dict[str, str] = {}
    main = letter = 0
    for key in order:
        if key.startswith("+"):
            letter += 1
            numbers[key[1:]] = f"{main}{chr(ord('a') + letter)}"
        else:
            main, letter = main + 1, 0
            numbers[key] = str(main)
    return numbers


NUMBERS = _numbers(PAGE_ORDER)
"""Each section's number on the page, by key."""


def heading(key: str, title: str) -> str:
    """The markdown heading of section `key`: ``## <number>. <title>``."""
    return f"## {NUMBERS[key]}. {title}"


def section(key: str) -> str:
    """How the page's text names section `key`: ``section <number>``."""
    return f"section {NUMBERS[key]}"
