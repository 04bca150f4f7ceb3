"""The results page's risk-levels section: the risk levels each HuRi-family agent sets on the states it
visits.

Every entry whose method has a quantile critic and reads the IQR band (``sb3_huri.huri.METHODS``: ``huri``,
``huri-no-rnd``, ``huri-percentile``, ``huri-cvar``), Zerith-1's and the quadruped's, with the file the
campaign (or ``study.scripts.risk_levels``) wrote for its checkpoint
(``study.analyses.risk_levels``): per scenario the shares of visited states below / within /
above the agent's own IQR band, the mean risk level and the mean and 90th percentile of its RND part; per
agent whether the paper's order holds (Fig. 5: more risk-averse on uneven ground than under pushes, and
under pushes than on the plane), what its RND part does, and whether its critic turns averse in the last
second before its robots' falls. An entry takes the file of its final evaluation's checkpoint, else the
first one measured at or after its steps and before the next entry of its run. The entries without one are
listed with the command that measures them.
"""

from __future__ import annotations

import math
import os
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from sb3_huri.experiments.markdown import table
from sb3_huri.runner.files import read_json
from study.analyses.risk_levels import (
    FALL_WINDOW_STEPS,
    RND_HIGH,
    ROLE_CASES,
    ROLES,
    TRAINING_SPEED_CASE,
    risk_levels_files,
)
from study.campaign import progress
from study.campaign.queue import CampaignEntry
from study.results.markdown import millions
from study.results.sections import heading
from zerith_gym.core.scenarios import TEST_COMMAND
from zerith_gym.zerith1.constants import CONTROL_DT

SCRIPT = "study/scripts/risk_levels.py"
ROLE_NAMES = {"plane": "on the plane", "push": "under pushes", "uneven": "on uneven ground"}
RND_INERT = 0.1
"""beta_RND below this at its 90th percentile in every case measured: beta is what the IQR band sets."""
RND_SATURATED = 0.9
"""beta_RND's mean above this in every case measured: it adds about 1 everywhere, a constant."""
RND_RARE = 0.05
"""beta_RND above 0.5 on fewer than this share of the states of every case: it nudges beta, no more."""


def risk_family(method: str) -> bool:
    """Whether ``method`` sets a risk level per state from the IQR band of a quantile critic."""
    from sb3_huri.huri.methods import METHODS

    preset = METHODS.get(method)
    return preset is not None and preset.distributional and preset.use_iqr


def evaluated_steps(entry: CampaignEntry) -> int | None:
    """The steps of the entry's final evaluation's checkpoint, if it was evaluated."""
    path = entry.evaluation()
    return None if path is None else int(read_json(path, "a final evaluation")["steps"])


def entry_file(entry: CampaignEntry, entries: Sequence[CampaignEntry]) -> Path | None:
    """The risk-levels file of the entry: its final evaluation's checkpoint's, else the first measured at or
    after its steps and before the next entry of its run; None if there is none."""
    files = risk_levels_files(entry.run)
    evaluated = evaluated_steps(entry)
    if evaluated in files:
        return files[evaluated]
    later = [other.steps for other in entries if other.run == entry.run and other.steps > entry.steps]
    limit = min(later, default=math.inf)
    candidates = [steps for steps in files if entry.steps <= steps < limit]
    return files[min(candidates)] if candidates else None


def _ordered_cases(data: dict[str, Any]) -> list[str]:
    """The file's cases, the roles' first (plane, push, uneven), then the others."""
    roles = [data["roles"][role] for role in ROLES if data["roles"][role] in data["cases"]]
    return [*roles, *(case for case in data["cases"] if case not in roles)]


def order_sentence(data: dict[str, Any]) -> str:
    """Whether the agent's mean risk level follows the paper's order, uneven > push > plane (Wang's beta; for
    CVaR a lower alpha is the more averse), said with the three means."""
    roles, cases = data["roles"], data["cases"]
    missing = [roles[role] for role in ROLES if roles[role] not in cases]
    if missing:
        return f"the paper's order cannot be read: {', '.join(f'`{case}`' for case in missing)} not measured"
    cvar = data["band"]["distortion"] == "cvar"
    name = "alpha" if cvar else "beta"
    means = {role: cases[roles[role]]["beta"] for role in ROLES}
    averse = {role: -value if cvar else value for role, value in means.items()}
    said = ", ".join(f"{means[role]:+.3f} {ROLE_NAMES[role]} (`{roles[role]}`)" for role in reversed(ROLES))
    broken = [
        f"not more risk-averse {ROLE_NAMES[higher]} than {ROLE_NAMES[lower]}"
        for higher, lower in (("uneven", "push"), ("push", "plane"))
        if not averse[higher] > averse[lower]
    ]
    if not broken:
        return (
            f"mean {name} {said}: the paper's order holds (more risk-averse on uneven ground than under "
            "pushes, and under pushes than on the plane)"
        )
    return f"mean {name} {said}: the paper's order does not hold ({'; '.join(broken)})"


def rnd_sentence(data: dict[str, Any]) -> str:
    """What beta_RND does in the agent's measured cases: its range, the test speed against the training
    speed on the plane, and whether it is inert, saturated or moves beta."""
    if not data["band"].get("use_rnd", True):
        return "no RND part (beta_RND = 0)"
    cases = data["cases"]
    if not cases:
        return "no case measured"
    means = {case: cases[case]["beta_rnd"] for case in cases}
    low, high = min(means, key=means.get), max(means, key=means.get)
    p90 = max(cases[case]["beta_rnd_p90"] for case in cases)
    if low == high:
        parts = [f"beta_RND's mean is {means[low]:.3f} (`{low}`, the one case measured)"]
    else:
        parts = [f"beta_RND's mean runs from {means[low]:.3f} (`{low}`) to {means[high]:.3f} (`{high}`)"]
    plane = data["roles"]["plane"]
    if plane in cases and TRAINING_SPEED_CASE in cases:
        parts.append(
            f"{means[plane]:.3f} on the plane at {TEST_COMMAND[0]:g} m/s against "
            f"{means[TRAINING_SPEED_CASE]:.3f} at the training speed (`{TRAINING_SPEED_CASE}`)"
        )
    if p90 < RND_INERT:
        reading = f"inert: its 90th percentile stays below {RND_INERT} in every case, beta is the band's"
    elif min(means.values()) > RND_SATURATED:
        reading = f"saturated: its mean is above {RND_SATURATED} in every case, a constant added to beta"
    elif max(case["beta_rnd_above_half"] for case in cases.values()) < RND_RARE:
        reading = (
            f"small: above {RND_HIGH} on fewer than {RND_RARE:.0%} of the states of every case, its 90th "
            f"percentile at most {p90:.3f}"
        )
    else:
        most = max(cases, key=lambda case: cases[case]["beta_rnd_above_half"])
        reading = (
            f"it moves beta: above {RND_HIGH} on {cases[most]['beta_rnd_above_half']:.0%} of the states of "
            f"`{most}`, against {cases[low]['beta_rnd_above_half']:.0%} in `{low}`"
        )
    return "; ".join(parts) + f"; {reading}"


def fall_sentence(data: dict[str, Any]) -> str:
    """Whether the critic turns averse before a fall: over the cases where a robot fell, the mean risk level
    and the share of states above the band in the last second before each fall, against their other
    states (pooled, each state weighing the same)."""
    cases = [values for values in data["cases"].values() if "falls" in values]
    if not cases:
        return "before a fall: not measured in this file"
    fell = [values for values in cases if values["falls"]]
    if not fell:
        return f"no robot fell in the {len(cases)} cases measured"
    pooled = {}
    for where, count in (("before_fall", "before_fall_states"), ("elsewhere", None)):
        weights = [
            values[count] if count else values["robot_steps"] - values["before_fall_states"]
            for values in fell
        ]
        for key in ("beta", "above"):
            pairs = [(w, values[f"{key}_{where}"]) for w, values in zip(weights, fell, strict=True) if w]
            total = sum(w for w, _ in pairs)
            pooled[key, where] = sum(w * v for w, v in pairs) / total if total else math.nan
    falls = sum(values["falls"] for values in fell)
    name = "alpha" if data["band"]["distortion"] == "cvar" else "beta"
    counted = f"{falls} fall{'s' if falls != 1 else ''} ({len(fell)} case{'s' if len(fell) != 1 else ''})"
    said = (
        f"in the last {FALL_WINDOW_STEPS * CONTROL_DT:g} s before its robots' {counted}, mean {name} "
        f"{pooled['beta', 'before_fall']:+.2f} and {pooled['above', 'before_fall']:.0%} of the states above "
        "the band"
    )
    if math.isnan(pooled["beta", "elsewhere"]):
        return f"{said}; those cases hold no other states"
    return (
        f"{said}, against {pooled['beta', 'elsewhere']:+.2f} and {pooled['above', 'elsewhere']:.0%} over the "
        "other states of those cases"
    )


def summary_lines(measured: Sequence[dict[str, Any]]) -> list[str]:
    """A line over the measured agents: the range of their shares of states below the band per role."""
    parts = []
    for role in ROLES:
        shares = [
            data["cases"][data["roles"][role]]["below"]
            for data in measured
            if data.get("roles", {}).get(role) in data["cases"]
        ]
        if shares:
            parts.append(f"{min(shares):.2f}-{max(shares):.2f} {ROLE_NAMES[role]}")
    if not parts:
        return []
    return [
        "Share of the visited states below the band (beta_IQR at its seeking level), over the "
        f"{len(measured)} agent{'s' if len(measured) != 1 else ''} measured: {', '.join(parts)}.",
        "",
    ]


def agent_cell(entry: CampaignEntry, data: dict[str, Any]) -> str:
    """The agent's cell: entry, measured step, band reading and thresholds."""
    band = data["band"]
    t_min, t_max = band["thresholds"]
    return f"{entry.name} @ {millions(int(data['steps']))}, {band['reading']} band [{t_min:.3f}, {t_max:.3f}]"


TABLE_COLUMNS = (
    ("below", "below band"),
    ("within", "within"),
    ("above", "above band"),
    ("beta", "mean beta"),
    ("beta_rnd", "mean beta_RND"),
    ("beta_rnd_p90", "beta_RND p90"),
    ("iqr_median", "IQR median"),
    ("survive", "survive"),
)


def _number(value: float) -> str:
    """A table cell: three decimals, "-" for a number not measured."""
    return f"{value:.3f}" if math.isfinite(value) else "-"


def _agent_lines(entry: CampaignEntry, path: Path) -> tuple[list[list[str]], list[str]]:
    """The agent's table rows (their cells) and its sentence."""
    data = read_json(path, "an agent's risk levels")
    data.setdefault("roles", ROLE_CASES.get(data.get("robot", "zerith1"), ROLE_CASES["zerith1"]))
    cell = agent_cell(entry, data)
    rows = []
    for case in _ordered_cases(data):
        values = data["cases"][case]
        cells = [_number(values.get(key, math.nan)) for key, _ in TABLE_COLUMNS]
        rows.append([cell, f"`{case}`", *cells])
    evaluated = evaluated_steps(entry)
    measured = int(data["steps"])
    note = "" if evaluated in (None, measured) else f" (its final evaluation: {millions(evaluated)})"
    sentence = (
        f"- {entry.name} at {millions(measured)}{note}: {order_sentence(data)}. {rnd_sentence(data)}. "
        f"{_sentence_start(fall_sentence(data))}. {data['settings']['robots']} robots per case."
    )
    return rows, [sentence]


def _sentence_start(text: str) -> str:
    return text[:1].upper() + text[1:]


def measure_command(entry: CampaignEntry, script: str = SCRIPT) -> str:
    """The command of ``script`` (a file of ``study/scripts/``, run as its module) that measures the entry's
    checkpoint, its run folder relative to here if it lies below."""
    module = Path(script).with_suffix("").as_posix().replace("/", ".")
    run = entry.run
    here = Path.cwd()
    shown = os.path.relpath(run, here) if run.is_relative_to(here) else str(run)
    return f"`python -m {module} {shown} --steps {evaluated_steps(entry) or entry.steps}`"


def risk_levels_section(entries: Sequence[CampaignEntry]) -> list[str]:
    """The risk-levels section: the risk levels of every HuRi-family entry (see the module docstring)."""
    lines = [
        heading("risk_levels", "Risk levels in use: the IQR band's shares, beta and beta_RND"),
        "",
        "The campaign measures each HuRi-family agent (its method reads the critic's IQR band) after its "
        f"final evaluation (`{SCRIPT}` does it by hand), on the same few "
        "robots per case, one 20-s episode each with the deterministic policy, and reads every state a "
        "robot visits before its episode ends. The shares: states whose critic IQR is below the agent's "
        "own band (beta_IQR = -1, risk-seeking for Wang), within it (0) or above it (+1, risk-averse), "
        "with the thresholds the agent reads (the absolute band: fixed in normalized-return units; the "
        "percentile band: percentiles of recent rollouts' IQRs, frozen outside training). Mean beta = "
        "beta_IQR + beta_RND (CVaR: alpha); beta_RND = tanh of the normalized RND error. The paper's Fig. "
        "5 order: more risk-averse on uneven ground than under pushes, and under pushes than on the plane "
        "(the quadruped: Table 8's platform under a centroid force, legged_gym's rough terrain). Before a "
        "fall: the states of each robot's last second before it fell, against the other states of the "
        "cases where robots fell; HuRi's premise is that the critic turns averse there.",
        "",
    ]
    family = [entry for entry in entries if risk_family(entry.method)]
    if not family:
        return [*lines, "No entry of the queue has a method that reads the IQR band.", ""]
    rows: list[list[str]] = []
    sentences, unmeasured, untrained, measured = [], [], [], []
    for entry in family:
        path = entry_file(entry, entries)
        state = progress.state(entry) if path is None else None
        if state in ("done", "evaluate"):
            unmeasured.append(f"- {entry.name} ({entry.method}): {measure_command(entry)}")
        elif path is None:
            untrained.append(entry.name)
        if path is None:
            continue
        measured.append(read_json(path, "an agent's risk levels"))
        agent_rows, sentence = _agent_lines(entry, path)
        rows += agent_rows
        sentences += sentence
    if sentences:
        header = ["agent", "scenario", *(name for _, name in TABLE_COLUMNS)]
        lines += [*table(header, rows), "", *summary_lines(measured), *sentences, ""]
    if unmeasured:
        lines += ["Not measured yet (each command measures the entry's checkpoint):", "", *unmeasured, ""]
    if untrained:
        lines += [
            "Not trained to their steps yet, or waiting for the campaign's analyses (it measures each after "
            "its final evaluation): "
            f"{', '.join(untrained)}.",
            "",
        ]
    return lines
