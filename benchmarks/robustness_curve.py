"""The robustness learning curve of a long run: its checkpoints evaluated on the paper's Table-1 scenarios.

For every checkpoint of a run (`<run>/checkpoints/rl_model_<steps>_steps.zip` and its normalizer, written by
`examples/train_zerith.py`) at least `--every` steps after the previous row of the curve, and for the run's
newest model, evaluates the deterministic policy on the six Table-1 scenarios (continuous and sudden forces on
centroid, hands and feet, at the test ranges and 1 m/s), on `side-impact` (one 200 N push from the side),
`nominal@1.0` and `nominal@0.5`, and appends a
row per checkpoint to `<run>/robustness.csv`: steps, the run's training wall time at that step (from
`curve.csv`) and the hardware it trained on (`state.json`), the episodes per case, the survival rate of
each case (`--episodes` robots, seeds `--seed` + i, the same for every checkpoint), the Table-1 mean and
the mean forward velocity at 1 m/s. A row evaluated with another number of episodes is evaluated again
with `--episodes` when its checkpoint is still there, and kept as it is otherwise.

    python benchmarks/robustness_curve.py runs/huri/Zerith1-v0_1                 # new checkpoints only
    python benchmarks/robustness_curve.py runs/huri/Zerith1-v0_1 --every 5000000 --episodes 50
    python benchmarks/robustness_curve.py runs/huri/Zerith1-v0_1 --docs docs/training.md  # docs' tables too
    python benchmarks/robustness_curve.py runs/huri/Zerith1-v0_1 --plot docs/media/robust-run.png
    python benchmarks/robustness_curve.py runs/huri/Zerith1-v0_1 --plot curve.png \
        --forks runs/huri/Zerith1-v0_3 --versus runs/huri-baseline/Zerith1-v0_1    # PPO beside it

With `--docs FILE`, the run's status (sessions, steps, wall time, curriculum, the update's figures) and the
robustness curve replace the text between `<!-- robust-run:begin -->` and `<!-- robust-run:end -->` in FILE.
"""

from __future__ import annotations

import argparse
import csv
import re
import tempfile
import time
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import torch as th

from sb3_huri.experiments.evaluation import TABLE1_SCENARIOS, wilson_interval
from sb3_huri.experiments.robustness import (
    CASES,
    NOMINAL,
    read_rows,
    robustness_row,
    training_hardware,
    wall_time_at,
    write_rows,
)
from sb3_huri.zoo import load_run
from sb3_huri.zoo.checkpoints import RunState

ENV_ID = "Zerith1-v0"

if TYPE_CHECKING:
    from matplotlib.figure import Figure


def checkpoints(run: Path) -> dict[int, tuple[Path, Path]]:
    """Model and normalizer of each saved checkpoint, by step; the run's newest model included."""
    found = {}
    for model in (run / "checkpoints").glob("rl_model_*_steps.zip"):
        steps = int(re.findall(r"_(\d+)_steps", model.name)[0])
        found[steps] = (model, run / "checkpoints" / f"rl_model_vecnormalize_{steps}_steps.pkl")
    newest = RunState.read(run).timesteps
    if newest and (run / f"{ENV_ID}.zip").is_file():
        found[newest] = (run / f"{ENV_ID}.zip", run / ENV_ID / "vecnormalize.pkl")
    return dict(sorted(found.items()))


def evaluate_checkpoint(
    model_file: Path, normalizer_file: Path, episodes: int, seed: int
) -> dict[str, float]:
    """Survival per case, the Table-1 mean and the mean forward velocity at 1 m/s."""
    with tempfile.TemporaryDirectory() as folder:  # RL Zoo's layout, which load_run reads
        layout = Path(folder)
        (layout / ENV_ID).mkdir()
        (layout / f"{ENV_ID}.zip").symlink_to(model_file.resolve())
        (layout / ENV_ID / "vecnormalize.pkl").symlink_to(normalizer_file.resolve())
        model, normalizer = load_run(layout, ENV_ID)
    return robustness_row(model, normalizer, episodes, seed)


STATUS_COLUMNS = (
    "ep_len", "ep_return", "fall_rate", "scale", "approx_kl", "clip_fraction", "explained_variance", "std",
    "learning_rate",
)  # fmt: skip


def _summary(rows: list[dict[str, str]], key: str) -> float:
    """The median of a column over rows, or for `fall_rate` the mean: a rollout ends only a few episodes,
    so its fall rate is mostly 0 or 1 and the median hides how many fell."""
    values = sorted(float(r[key]) for r in rows if r[key] not in ("", "nan"))
    if not values:
        return float("nan")
    return sum(values) / len(values) if key == "fall_rate" else values[len(values) // 2]


def status_markdown(run: Path) -> str:
    """The run's sessions, and its training figures per 1M-step block and over the whole run."""
    state = RunState.read(run)
    with (run / "curve.csv").open() as file:
        rows = list(csv.DictReader(file))
    lines = [
        f"{state.timesteps:,} steps in {state.wall_s / 3600:.2f} h of training over {len(state.sessions)} "
        f"session(s); curriculum stage {state.curriculum_stage} (scale {rows[-1]['scale']}).",
        "",
        "| session started | steps | wall (min) | hardware |",
        "|---|---|---|---|",
    ]
    for session in state.sessions:
        steps = f"{session['from_timesteps']:,} -> {session.get('to_timesteps', session['from_timesteps']):,}"
        wall = session.get("wall_s", 0.0) / 60
        lines.append(f"| {session['started']} | {steps} | {wall:.0f} | {session['hardware']} |")
    lines += [
        "",
        "Per 1M steps, medians over the updates (`curve.csv`): mean training episode length and",
        "return, share of ended episodes that fell (the mean over rollouts, not the median), curriculum",
        "scale, approximate KL, clip fraction, critic explained variance, action noise, the actor's mean",
        "learning rate:",
        "",
        "| steps | wall (h) | ep len | return | falls | scale | approx_kl | clip | expl. var. | std | lr |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    blocks: dict[int, list[dict[str, str]]] = {}
    for row in rows:
        blocks.setdefault(int(row["timesteps"]) // 1_000_000, []).append(row)
    for block, members in [*blocks.items(), (-1, rows)]:
        label = "whole run" if block < 0 else f"{block}-{block + 1}M"
        wall = float(members[-1]["wall_s"]) / 3600
        cells = [_summary(members, key) for key in STATUS_COLUMNS]
        formatted = [f"{cells[0]:.0f}", f"{cells[1]:.0f}", *(f"{v:.3g}" for v in cells[2:])]
        lines.append(f"| {label} | {wall:.2f} | " + " | ".join(formatted) + " |")
    return "\n".join(lines)


TREND_CASES = ("table1_mean", "continuous-feet", "sudden-feet", "vx_at_1.0")
"""The columns whose trend since full scale the docs state: the Table-1 mean, the lagging feet cases and the
forward velocity at a 1 m/s command (m/s; a shipped agent must reach 0.8)."""


def trend(steps: np.ndarray, values: np.ndarray) -> tuple[float, float]:
    """Least-squares slope of `values` per 10M `steps` and the half-width of its 95% t interval.

    Whether a curve still rises is read from the slope over its points, not from two noisy ends."""
    from scipy import stats

    if len(steps) < 3:
        raise ValueError(f"a trend needs at least 3 points, got {len(steps)}")
    fit = stats.linregress(np.asarray(steps, dtype=float) / 1e7, np.asarray(values, dtype=float))
    return float(fit.slope), float(fit.stderr * stats.t.ppf(0.975, len(steps) - 2))


def full_scale_step(run: Path) -> int | None:
    """The first step at which the run's curriculum scale reached 1 (`curve.csv`), or None."""
    with (run / "curve.csv").open() as file:
        for row in csv.DictReader(file):
            if row.get("scale") not in (None, "", "nan") and float(row["scale"]) >= 1.0:
                return int(row["timesteps"])
    return None


RECENT_STEPS = 50_000_000
"""The window of the second trend the docs state: has the curve flattened lately?"""


def _slopes(rows: list[dict[str, str]]) -> str:
    steps = np.array([int(r["timesteps"]) for r in rows])
    parts = []
    for key in TREND_CASES:
        slope, half = trend(steps, np.array([float(r[key]) for r in rows]))
        parts.append(f"{key} {slope:+.3f} +- {half:.3f}")
    return ", ".join(parts)


def trend_markdown(run: Path, rows: list[dict[str, str]]) -> str:
    """How fast the curve rose since the curriculum reached full scale and over the last `RECENT_STEPS`
    (when that window starts later and holds 3 rows), or "" if too early."""
    since = full_scale_step(run)
    later = [r for r in rows if since is not None and int(r["timesteps"]) >= since]
    if len(later) < 3:
        return ""
    text = (
        f"Since the curriculum reached full scale ({since:,} steps), per 10M steps (least-squares slope over "
        f"{len(later)} rows, 95% t interval): {_slopes(later)}."
    )
    start = int(later[-1]["timesteps"]) - RECENT_STEPS
    recent = [r for r in later if int(r["timesteps"]) >= start]
    if start > int(later[0]["timesteps"]) and len(recent) >= 3:
        text += f" Over the last {RECENT_STEPS / 1e6:.0f}M steps ({len(recent)} rows): {_slopes(recent)}."
    return text


SHIP_MEAN = 0.8
SHIP_CASE_FLOOR = 0.6
SHIP_VX = 0.8
"""Shipping criteria of a robust agent: the Table-1 mean, the least any Table-1 case may survive and the
forward velocity at a 1 m/s command (m/s); `nominal@1.0` and `nominal@0.5` must also pass without a fall."""


def unmet_ship_criteria(row: dict[str, str]) -> list[str]:
    """The shipping criteria a row of the curve misses, each said with its number ([] when it ships)."""
    unmet = []
    if float(row["table1_mean"]) < SHIP_MEAN:
        unmet.append(f"Table-1 mean {float(row['table1_mean']):.3f} < {SHIP_MEAN}")
    unmet += [
        f"{case} {float(row[case]):.2f} < {SHIP_CASE_FLOOR}"
        for case in TABLE1_SCENARIOS
        if float(row[case]) < SHIP_CASE_FLOOR
    ]
    if float(row["vx_at_1.0"]) < SHIP_VX:
        unmet.append(f"vx at 1 m/s {float(row['vx_at_1.0']):.2f} < {SHIP_VX}")
    unmet += [f"{case} falls ({float(row[case]):.2f} survive)" for case in NOMINAL if float(row[case]) < 1.0]
    return unmet


def ship_markdown(rows: list[dict[str, str]]) -> str:
    """Which rows meet the shipping criteria, or what the newest row misses."""
    ready = [f"{int(r['timesteps']):,}" for r in rows if not unmet_ship_criteria(r)]
    if ready:
        return f"Rows that meet the shipping criteria: {', '.join(ready)} steps."
    return (
        "No row meets the shipping criteria yet; the newest misses: "
        + "; ".join(unmet_ship_criteria(rows[-1]))
        + "."
    )


def curve_markdown(run: Path) -> str:
    """The robustness curve as a table, with the 95% interval of the newest Table-1 mean."""
    rows = list(read_rows(run).values())
    if not rows:
        return "(no checkpoint evaluated yet)"
    header = ["steps", "wall (h)", "episodes", *CASES, "Table-1 mean", "vx @ 1.0"]
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    for row in rows:
        steps, wall = f"{int(row['timesteps']):,}", f"{float(row['wall_s']) / 3600:.2f}"
        cells = [steps, wall, row["episodes"], *(row[c] for c in CASES), row["table1_mean"], row["vx_at_1.0"]]
        lines.append("| " + " | ".join(cells) + " |")
    episodes = int(rows[-1]["episodes"])
    n = episodes * len(TABLE1_SCENARIOS)
    low, high = wilson_interval(float(rows[-1]["table1_mean"]), n)
    one_low, one_high = wilson_interval(0.5, episodes)
    lines += [
        "",
        f"{episodes} episodes per case in the newest row: its Table-1 mean ({n} episodes) lies in "
        f"[{low:.2f}, {high:.2f}] (95% Wilson interval); one case's share is known to about "
        f"+-{(one_high - one_low) / 2:.2f}.",
        "",
        ship_markdown(rows),
    ]
    sentence = trend_markdown(run, rows)
    return "\n".join([*lines, "", sentence] if sentence else lines)


def fork_own_rows(
    run_rows: dict[int, dict[str, str]], fork_rows: dict[int, dict[str, str]]
) -> list[tuple[int, dict[str, str]]]:
    """A fork's own rows, from the last row it shares with its run on: a row is shared when the run has
    the same row at the same step (the fork's `robustness.csv` starts as a copy of the run's). Rows at the
    same step but evaluated differently are the fork's own: after the fork both go on from the same step
    count, so their checkpoints carry the same step numbers."""
    rows = list(fork_rows.items())
    first = next((i for i, (s, r) in enumerate(rows) if run_rows.get(s) != r), len(rows))
    return rows[max(first - 1, 0) :] if first < len(rows) else []


FORK_COLORS = ("tab:red", "tab:purple", "tab:olive", "teal", "darkgoldenrod", "magenta")
"""The colors of the forks' lines, in order (taken again from the first past the last)."""
VERSUS_COLORS = ("tab:blue", "tab:green", "tab:brown")
"""The colors of other methods' lines (`--versus`), in order."""


def _mean_line(rows: list[dict[str, str]]) -> tuple[np.ndarray, np.ndarray]:
    """The Table-1 mean of `rows` by training steps in millions, as a plot's x and y."""
    steps = np.array([int(r["timesteps"]) for r in rows]) / 1e6
    return steps, np.array([float(r["table1_mean"]) for r in rows])


def plot_curve(run: Path, path: Path, forks: tuple[Path, ...] = (), versus: tuple[Path, ...] = ()) -> Figure:
    """The robustness curve as a figure: each Table-1 case and `side-impact` by training steps, the Table-1
    mean with its 95% Wilson band, and the curriculum's scale (`curve.csv`) on a second axis. Each run of
    `forks` (a copy of `run` trained on from one of its checkpoints) adds its Table-1 mean over its own
    rows (`fork_own_rows`); each run of `versus` (another method's run, e.g. PPO with the same recipe) its
    Table-1 mean over all its rows, dashed, labelled `<algo>/<run>`. Returns the figure it saved to `path`."""
    from matplotlib.figure import Figure

    run_rows = read_rows(run)
    rows = list(run_rows.values())
    if not rows:
        raise ValueError(f"{run} has no evaluated checkpoint to plot (robustness.csv)")
    steps, mean = _mean_line(rows)
    figure = Figure(figsize=(8, 5.2), layout="constrained")
    axes = figure.add_subplot()
    for case in (*TABLE1_SCENARIOS, "side-impact"):
        style = ":" if case == "side-impact" else "-"
        axes.plot(steps, [float(r[case]) for r in rows], style, lw=1, alpha=0.7, label=case)
    cases = len(TABLE1_SCENARIOS)
    bands = [wilson_interval(m, int(r["episodes"]) * cases) for m, r in zip(mean, rows, strict=True)]
    axes.fill_between(steps, [b[0] for b in bands], [b[1] for b in bands], color="black", alpha=0.15)
    axes.plot(steps, mean, "k-", lw=2.5, label="Table-1 mean (95% band)")
    for index, fork in enumerate(forks):
        color = FORK_COLORS[index % len(FORK_COLORS)]
        own = fork_own_rows(run_rows, read_rows(fork))
        if not own:
            raise ValueError(f"{fork} has no evaluated checkpoint beyond those of {run} (robustness.csv)")
        label = f"{fork.name}: Table-1 mean"
        axes.plot(*_mean_line([r for _, r in own]), "-", color=color, lw=2.5, label=label)
    for index, other in enumerate(versus):
        other_rows = list(read_rows(other).values())
        if not other_rows:
            raise ValueError(f"{other} has no evaluated checkpoint to plot (robustness.csv)")
        axes.plot(*_mean_line(other_rows), "--", lw=2.5,
                  color=VERSUS_COLORS[index % len(VERSUS_COLORS)],
                  label=f"{other.parent.name}/{other.name}: Table-1 mean")  # fmt: skip
    axes.set_xlabel("environment steps (millions)")
    axes.set_ylabel("survival rate (20-s episodes)")
    axes.set_ylim(-0.02, 1.02)
    axes.grid(alpha=0.3)
    with (run / "curve.csv").open() as file:
        curve = [(int(r["timesteps"]) / 1e6, float(r["scale"])) for r in csv.DictReader(file)]
    scale_axes = axes.twinx()
    scale_axes.plot([c[0] for c in curve], [c[1] for c in curve], color="tab:gray", lw=1, ls="--")
    scale_axes.set_ylabel("curriculum scale (dashed)", color="tab:gray")
    scale_axes.set_ylim(-0.02, 1.02)
    figure.legend(fontsize=7, loc="outside lower center", ncol=4)
    axes.set_title(f"{run.name}: survival under the paper's test disturbances, by training steps")
    figure.savefig(path, dpi=110)
    return figure


def update_docs(run: Path, docs: Path) -> None:
    """Replace the run's section of `docs` (between the robust-run markers) with its current tables."""
    begin, end = "<!-- robust-run:begin -->", "<!-- robust-run:end -->"
    text = docs.read_text()
    if begin not in text or end not in text:
        raise ValueError(f"{docs} has no {begin} ... {end} section to replace")
    head, rest = text.split(begin, 1)
    tail = rest.split(end, 1)[1]
    body = f"{status_markdown(run)}\n\nRobustness curve:\n\n{curve_markdown(run)}"
    docs.write_text(f"{head}{begin}\n{body}\n{end}{tail}")


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("run", type=Path, help="a run folder written by examples/train_zerith.py")
    parser.add_argument(
        "--every", type=int, default=5_000_000, help="env steps between evaluated checkpoints"
    )
    parser.add_argument("--episodes", type=int, default=50, help="episodes per case (default 50)")
    parser.add_argument("--seed", type=int, default=1000)
    parser.add_argument("--docs", type=Path, default=None, help="also write the run's tables into this file")
    parser.add_argument("--plot", type=Path, default=None, help="also draw the curve into this image file")
    parser.add_argument(
        "--forks",
        type=Path,
        nargs="+",
        default=[],
        help="runs forked from this one: their Table-1 mean in the plot",
    )
    parser.add_argument(
        "--versus",
        type=Path,
        nargs="+",
        default=[],
        help="other methods' runs (e.g. PPO with the same recipe): their Table-1 mean in the plot, dashed",
    )
    args = parser.parse_args()
    th.set_num_threads(1)
    rows = read_rows(args.run)
    found = checkpoints(args.run)
    newest = max(found, default=None)
    for steps, (model_file, normalizer_file) in found.items():
        row = rows.get(steps)
        if row is not None and int(row["episodes"]) == args.episodes:
            continue
        previous = max((s for s in rows if s < steps), default=-args.every)  # kept rows count too
        if row is None and steps - previous < args.every and steps != newest:
            continue  # a row of another episode count is redone wherever its checkpoint is still there
        began = time.time()
        metrics = evaluate_checkpoint(model_file, normalizer_file, args.episodes, args.seed)
        trained = {"timesteps": steps, "wall_s": wall_time_at(args.run, steps)}
        trained["hardware"] = training_hardware(args.run, steps)
        rows[steps] = {**trained, "episodes": args.episodes, **metrics, "eval_s": round(time.time() - began)}
        write_rows(args.run, rows)
        print(rows[steps], flush=True)
        print("unmet shipping criteria:", unmet_ship_criteria(rows[steps]) or "none", flush=True)
    if args.docs is not None:
        update_docs(args.run, args.docs)
    if args.plot is not None:
        plot_curve(args.run, args.plot, tuple(args.forks), tuple(args.versus))


if __name__ == "__main__":
    main()
