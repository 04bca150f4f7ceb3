"""The campaign's final evaluation (``final_evaluation``) and its results page (``results``).

The page is built from a synthetic queue and synthetic run folders, and its numbers are checked against
computations made here independently (scipy's Wilson interval and t quantiles, counts of robots); the
evaluation runs on a real, untrained model with two robots and three-step episodes.
"""

from __future__ import annotations

import json
import math
import random
import re
from pathlib import Path

import numpy as np
import pytest
import torch as th
import yaml
from scipy import stats

from sb3_huri.experiments.errors import ExperimentError
from sb3_huri.experiments.statistics import paired_difference_interval
from sb3_huri.runner import record
from sb3_huri.runner.curve import CURVE_COLUMNS, append_row
from sb3_huri.runner.evaluation import (
    PLANE_CASE,
    RISK_CASES,
    TABLE1_SCENARIOS,
    TERRAIN_SCENARIOS,
    RiskTrace,
    write_trace,
)
from sb3_huri.runner.record import trace_path
from study.campaign import progress
from study.campaign.final_evaluation import EVALUATION_CASES, evaluate_entry, find_checkpoint
from study.campaign.queue import CampaignEntry, QueueDefaults, load_queue
from study.results import write_results

ENV = "Zerith1-v0"
ROBOTS = 40
ROLLOUT = 32  # n_envs * n_steps of the synthetic runs' config.yml
CASES = (
    *TABLE1_SCENARIOS,
    "side-impact",
    "load",
    "friction",
    "load-friction",
    *RISK_CASES,
    *TERRAIN_SCENARIOS,
)


def _run(folder: Path, steps: int, wall_s: float, hardware: str) -> None:
    """A run folder as the trainer leaves it: state, preset, learning and robustness curves."""
    (folder / ENV).mkdir(parents=True)
    session = {"started": "2026-01-01 00:00:00", "from_timesteps": 0, "to_timesteps": steps}
    state = {"timesteps": steps, "wall_s": wall_s, "sessions": [{**session, "hardware": hardware}]}
    (folder / ENV / "state.json").write_text(json.dumps(state))
    (folder / ENV / "config.yml").write_text(yaml.safe_dump({"n_envs": 4, "n_steps": 8}))
    for step in range(0, steps + 1, ROLLOUT):
        scale = min(step / 500, 1.0)
        row = {"timesteps": step, "wall_s": step / 10, "ep_return": 50 + step / 20, "scale": scale}
        append_row(folder, {**dict.fromkeys(CURVE_COLUMNS, math.nan), **row})
    rows = ["timesteps,table1_mean,episodes"] + [f"{s},{s / 2000:.3f},10" for s in (0, 500, 1000)]
    (folder / "robustness.csv").write_text("\n".join(rows) + "\n")


def _evaluation(
    folder: Path, name: str, method: str, seed: int, steps: int, rng: np.random.Generator
) -> dict:
    """An evaluation file of random per-robot outcomes; returns the outcomes written, by case."""
    survive_rate = 0.8 if method == "huri" else 0.6
    outcomes = {case: rng.random(ROBOTS) < survive_rate for case in CASES}
    cases = {
        case: {
            "survive": float(alive.mean()),
            "survived": alive.astype(int).tolist(),
            "fall_step": [None if a else 10 for a in alive],
            "lin_err": 0.2 + 0.01 * seed,
            "yaw_err": 0.3,
            "iqr": {"uneven": 0.9, "sudden-centroid": 0.5, PLANE_CASE: 0.2}.get(case, math.nan),
            "beta": 0.1,
        }
        for case, alive in outcomes.items()
    }
    data = {
        "entry": name, "protocol": "robust", "method": method, "seed": seed, "steps": steps,
        "wall_s": steps / 10, "hardware": ["test machine"], "eval_s": 1.0, "model": f"{ENV}.zip",
        "settings": {"episodes": ROBOTS, "seed": 2000, "episode_steps": 1000}, "cases": cases,
    }  # fmt: skip
    (folder / "evaluations").mkdir(exist_ok=True)
    (folder / "evaluations" / f"{steps}.json").write_text(json.dumps(data))
    return outcomes


@pytest.fixture(scope="module")
def campaign(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, dict[str, dict]]:
    """A queue of five entries: HuRi seeds 0 and 1 and PPO seed 0 evaluated (HuRi and PPO seed 0 one
    rollout apart at most), PPO seed 0 on to a later target (training) and HuRi seed 2 (new)."""
    root = tmp_path_factory.mktemp("campaign")
    (root / "preset.yml").write_text("Zerith1-v0: {}\n")
    rng = np.random.default_rng(7)
    _run(root / "huri" / f"{ENV}_1", 1010, 3600.0, "machine A")
    _run(root / "huri" / f"{ENV}_2", 1000, 7200.0, "machine B")
    _run(root / "huri-baseline" / f"{ENV}_1", 1000, 1800.0, "machine A")
    outcomes = {
        "huri-s0": _evaluation(root / "huri" / f"{ENV}_1", "huri-s0", "huri", 0, 1010, rng),
        "huri-s1": _evaluation(root / "huri" / f"{ENV}_2", "huri-s1", "huri", 1, 1000, rng),
        "ppo-s0": _evaluation(root / "huri-baseline" / f"{ENV}_1", "ppo-s0", "huri-baseline", 0, 1000, rng),
    }
    trace = RiskTrace(np.linspace(0, 1, 5), np.linspace(0.2, 0.4, 5), np.zeros((5, 8)), np.zeros(5), 0.5, 0.3)
    for case in RISK_CASES:
        write_trace(trace_path(root / "huri" / f"{ENV}_1", 1010, case), trace)
    entries = [
        ("huri-s0", "huri", 0, "huri/Zerith1-v0_1", 1000),
        ("huri-s1", "huri", 1, "huri/Zerith1-v0_2", 1000),
        ("ppo-s0", "huri-baseline", 0, "huri-baseline/Zerith1-v0_1", 1000),
        ("ppo-s0-long", "huri-baseline", 0, "huri-baseline/Zerith1-v0_1", 5000),
        ("huri-s2", "huri", 2, "huri/Zerith1-v0_3", 1000),
    ]
    keys = ("name", "method", "seed", "run", "steps")
    queue = {
        "entries": [
            {**dict(zip(keys, e, strict=True)), "protocol": "robust", "conf": "preset.yml"} for e in entries
        ]
    }
    (root / "campaign.yml").write_text(yaml.safe_dump(queue))
    write_results(root / "campaign.yml", root / "docs" / "results.md")
    return root, outcomes


def _page(root: Path) -> str:
    return (root / "docs" / "results.md").read_text()


def _row(page: str, first_cell: str, after: str = "") -> list[str]:
    """The cells of the first table row (after the text ``after``) whose first cell is ``first_cell``."""
    for line in page[page.index(after) :].splitlines():
        cells = [cell.strip() for cell in line.strip().strip("|").split("|")]
        if line.startswith("|") and cells[0] == first_cell:
            return cells
    raise AssertionError(f"no row {first_cell!r} after {after!r}")


def test_status_table_gives_each_entry_its_state_steps_and_hardware(campaign) -> None:
    root, _ = campaign
    page = _page(root)
    header = _row(page, "entry", "## 1.")
    state = header.index("state")
    assert _row(page, "huri-s0", "## 1.")[state] == "done (evaluated at 1,010)"
    assert _row(page, "ppo-s0", "## 1.")[state] == "done (evaluated at 1,000)"
    assert _row(page, "ppo-s0-long", "## 1.")[state] == "train"
    assert _row(page, "huri-s2", "## 1.")[state] == "new"
    huri = _row(page, "huri-s0", "## 1.")
    assert huri[header.index("steps / target")] == "1,010 / 1,000"
    assert huri[header.index("training h")] == f"{1010 / 10 / 3600:.2f}"  # wall time at the evaluated step
    assert huri[header.index("hardware")] == "test machine"
    assert "Still training: ppo-s0-long." in page


def test_survival_cells_are_wilson_intervals(campaign) -> None:
    root, outcomes = campaign
    page = _page(root)
    header = _row(page, "agent", "## 2.")
    for case in (*TABLE1_SCENARIOS, "side-impact"):
        alive = outcomes["huri-s0"][case]
        low, high = stats.binomtest(int(alive.sum()), alive.size).proportion_ci(method="wilson")
        expected = f"{alive.mean():.2f} [{low:.2f}, {high:.2f}]"
        assert _row(page, "huri-s0", "## 2.")[header.index(case)] == expected


def test_table1_mean_and_its_mean_over_seeds_use_students_t(campaign) -> None:
    root, outcomes = campaign
    page = _page(root)
    header = _row(page, "agent", "## 2.")
    column = header.index("Table-1 mean")
    per_robot = np.mean([outcomes["huri-s0"][case] for case in TABLE1_SCENARIOS], axis=0)
    half = stats.t.ppf(0.975, ROBOTS - 1) * per_robot.std(ddof=1) / math.sqrt(ROBOTS)
    mean = per_robot.mean()
    assert _row(page, "huri-s0", "## 2.")[column] == f"{mean:.3f} [{mean - half:.3f}, {mean + half:.3f}]"
    seeds = [np.mean([outcomes[n][c].mean() for c in TABLE1_SCENARIOS]) for n in ("huri-s0", "huri-s1")]
    half = stats.t.ppf(0.975, 1) * np.std(seeds, ddof=1) / math.sqrt(2)
    assert _row(page, "**mean over seeds 0, 1**", "## 2.")[column] == f"{np.mean(seeds):.3f} ± {half:.3f} (2)"
    assert "Baseline (PPO), robust protocol: one seed (0): an anecdote, no interval over seeds yet." in page


def test_paired_differences_are_huri_minus_ppo_on_the_same_robots(campaign) -> None:
    root, outcomes = campaign
    page = _page(root)
    after = "**huri-s0 @ 0.0M minus ppo-s0 @ 0.0M**"
    assert after in page  # 1,010 and 1,000 steps: within one rollout (32), so paired
    assert "huri-s1 @ 0.0M minus ppo-s0" not in page  # another seed: not paired
    huri, ppo = outcomes["huri-s0"], outcomes["ppo-s0"]
    for case in (*TABLE1_SCENARIOS, "side-impact"):
        cells = _row(page, case, after)
        difference, low, high = paired_difference_interval(huri[case], ppo[case])
        assert difference == pytest.approx(huri[case].mean() - ppo[case].mean())
        assert cells[3] == f"{difference:+.3f} [{low:+.3f}, {high:+.3f}]"
        assert cells[4:6] == [str(np.sum(huri[case] & ~ppo[case])), str(np.sum(~huri[case] & ppo[case]))]
        includes_zero = low <= 0 <= high
        assert ("no difference measured" in cells[6]) == includes_zero
    differences = np.mean([huri[c].astype(float) - ppo[c] for c in TABLE1_SCENARIOS], axis=0)
    half = stats.t.ppf(0.975, ROBOTS - 1) * differences.std(ddof=1) / math.sqrt(ROBOTS)
    mean = differences.mean()
    cells = _row(page, "Table-1 mean (t over robots)", after)
    assert cells[3] == f"{mean:+.3f} [{mean - half:+.3f}, {mean + half:+.3f}]"
    assert f"Table-1 mean on the same robots: {cells[3]}" in page  # the finding at the top says it too


def test_the_terrain_section_shows_every_agent_and_pairs_them_on_the_terrain_cases(campaign) -> None:
    root, outcomes = campaign
    page = _page(root)
    section = page[page.index("## 9.") :]
    header = _row(section, "agent")
    for case in TERRAIN_SCENARIOS:
        alive = outcomes["huri-s1"][case]
        low, high = stats.binomtest(int(alive.sum()), alive.size).proportion_ci(method="wilson")
        assert _row(section, "huri-s1")[header.index(case)] == f"{alive.mean():.2f} [{low:.2f}, {high:.2f}]"
    paper_huri = _row(section, "*paper: HuRi*")
    assert paper_huri[header.index("multi-terrain")] == "0.578"  # Table 9; Table 8 is the quadruped's
    assert paper_huri[header.index("platform-0.40")] == "-"
    after = "**huri-s0 @ 0.0M minus ppo-s0 @ 0.0M**"
    huri, ppo = outcomes["huri-s0"], outcomes["ppo-s0"]
    for case in TERRAIN_SCENARIOS:
        difference, low, high = paired_difference_interval(huri[case], ppo[case])
        assert _row(section, case, after)[3] == f"{difference:+.3f} [{low:+.3f}, {high:+.3f}]"
    assert "Table-1 mean (t over robots)" not in section  # section 2 has it; these are other cases
    assert "No HuRi-PPO pair of the `terrain` protocol is evaluated yet." in section


def test_methods_that_share_a_ppo_evaluation_stand_side_by_side_and_against_huri(tmp_path: Path) -> None:
    """HuRi and the percentile band, both paired with one PPO evaluation: each minus PPO and the percentile
    band minus HuRi in one table, that comparison in full, and a finding; a method of another seed not."""
    (tmp_path / "preset.yml").write_text("Zerith1-v0: {}\n")
    rng = np.random.default_rng(3)
    runs = {"huri-s0": ("huri", 0), "pct-s0": ("huri-percentile", 0), "ppo-s0": ("huri-baseline", 0),
            "pct-s1": ("huri-percentile", 1)}  # fmt: skip
    outcomes, entries = {}, []
    for index, (name, (method, seed)) in enumerate(runs.items()):
        folder = tmp_path / method / f"{ENV}_{index}"
        _run(folder, 1000, 100.0, "machine A")
        outcomes[name] = _evaluation(folder, name, method, seed, 1000 + index, rng)
        entries.append({"name": name, "protocol": "robust", "method": method, "seed": seed, "steps": 1000,
                        "run": f"{method}/{ENV}_{index}", "conf": "preset.yml"})  # fmt: skip
    (tmp_path / "campaign.yml").write_text(yaml.safe_dump({"entries": entries}))
    for index, name, shares in ((0, "huri-s0", (0.02, 0.04)), (1, "pct-s0", (0.10, 0.20))):
        measures = [{"level": 0.0, "correlation": 0.9, "sign_changes": 0.2, "weighted_sign_changes": w}
                    for w in shares]  # fmt: skip
        rollouts = [{"risk_mean": 0.0, "risk_sd": 0.5, "neutral": m, "constant": m} for m in measures]
        settings = {"rollouts": 2, "robots": 4, "rollout_steps": 8}
        record = {"steps": 1000 + index, "curriculum": None, "settings": settings, "rollouts": rollouts}
        folder = tmp_path / runs[name][0] / f"{ENV}_{index}" / "evaluations"
        (folder / f"{1000 + index}-advantages.json").write_text(json.dumps(record))
    page = write_results(tmp_path / "campaign.yml", tmp_path / "docs" / "results.md").read_text()
    section = page[page.index("### Methods side by side") : page.index("## 3.")]
    assert (
        "the risk distortion turns around against the neutral level: HuRi 0.030, huri-percentile 0.150."
        in section
    )
    assert "pct-s1" not in section  # seed 1 shares no PPO evaluation with HuRi
    after = "**Methods side by side, robust protocol, seed 0**"
    header = _row(section, "case", after)
    assert header[1:] == ["HuRi minus PPO", "huri-percentile minus PPO", "huri-percentile minus HuRi"]
    comparisons = [("huri-s0", "ppo-s0"), ("pct-s0", "ppo-s0"), ("pct-s0", "huri-s0")]
    for case in (*TABLE1_SCENARIOS, "side-impact"):
        expected = []
        for first, second in comparisons:
            difference, low, high = paired_difference_interval(outcomes[first][case], outcomes[second][case])
            expected.append(f"{difference:+.3f} [{low:+.3f}, {high:+.3f}]")
        assert _row(section, case, after)[1:] == expected
    differences = np.mean(
        [outcomes["pct-s0"][c].astype(float) - outcomes["huri-s0"][c] for c in TABLE1_SCENARIOS], 0
    )
    half = stats.t.ppf(0.975, ROBOTS - 1) * differences.std(ddof=1) / math.sqrt(ROBOTS)
    mean_cell = (
        f"{differences.mean():+.3f} [{differences.mean() - half:+.3f}, {differences.mean() + half:+.3f}]"
    )
    assert _row(section, "Table-1 mean (t over robots)", after)[3] == mean_cell
    full = "**pct-s0 @ 0.0M minus huri-s0 @ 0.0M** (robust, seed 0)"
    only = np.sum(outcomes["pct-s0"]["continuous-feet"] & ~outcomes["huri-s0"]["continuous-feet"])
    assert _row(section, "continuous-feet", full)[4] == str(only)  # robots only the percentile band kept up
    finding = "- huri-percentile minus HuRi, robust protocol, seed 0 (0.0M vs 0.0M steps), Table-1 mean on "
    assert f"{finding}the same robots: {mean_cell}" in page


def test_two_seeds_of_a_pair_give_the_comparison_over_seeds_and_lead_the_headline(tmp_path: Path) -> None:
    """HuRi and PPO seeds 0 and 1: each seed's paired Table-1 difference, their mean with a t interval over
    the two seeds (1 degree of freedom) and the count, in section 2 and first in the headline."""
    (tmp_path / "preset.yml").write_text("Zerith1-v0: {}\n")
    rng = np.random.default_rng(11)
    outcomes, entries = {}, []
    for index, (method, seed) in enumerate((m, s) for s in (0, 1) for m in ("huri", "huri-baseline")):
        name, folder = f"{method}-s{seed}", tmp_path / method / f"{ENV}_{index}"
        _run(folder, 1000, 100.0, "machine A")
        outcomes[name] = _evaluation(folder, name, method, seed, 1000, rng)
        entries.append({"name": name, "protocol": "robust", "method": method, "seed": seed, "steps": 1000,
                        "run": f"{method}/{ENV}_{index}", "conf": "preset.yml"})  # fmt: skip
    (tmp_path / "campaign.yml").write_text(yaml.safe_dump({"entries": entries}))
    page = write_results(tmp_path / "campaign.yml", tmp_path / "docs" / "results.md").read_text()
    per_seed = []
    for seed in (0, 1):
        huri, ppo = outcomes[f"huri-s{seed}"], outcomes[f"huri-baseline-s{seed}"]
        robots = np.mean([huri[c].astype(float) - ppo[c] for c in TABLE1_SCENARIOS], axis=0)
        half = stats.t.ppf(0.975, ROBOTS - 1) * robots.std(ddof=1) / math.sqrt(ROBOTS)
        per_seed.append(robots.mean())
        cell = f"{robots.mean():+.3f} [{robots.mean() - half:+.3f}, {robots.mean() + half:+.3f}]"
        assert _row(page, str(seed), "**HuRi minus PPO over seeds**")[2] == cell
    mean = np.mean(per_seed)
    half = stats.t.ppf(0.975, 1) * np.std(per_seed, ddof=1) / math.sqrt(2)
    over = f"{mean:+.3f} [{mean - half:+.3f}, {mean + half:+.3f}]"
    assert _row(page, "**mean over 2 seeds** (t over seeds)", "### Over seeds")[2] == over
    headline = page[page.index("## What the numbers show") :].splitlines()[2]
    below = sum(d < 0 for d in per_seed)
    assert headline.startswith("- **Over 2 seeds (0, 1), HuRi minus PPO, robust protocol, ~0.0M steps, ")
    assert (
        f"Table-1 mean on the same robots: {over} (95% t interval over the seeds); below 0 in {below} of 2"
        in headline
    )


def test_one_seed_per_method_is_said_first(campaign) -> None:
    root, _ = campaign
    headline = _page(root)[_page(root).index("## What the numbers show") :].splitlines()[2]
    assert headline.startswith("- **Every comparison below rests on one seed per method**")


def test_the_value_baseline_section_shows_each_measured_agent_and_the_command_for_the_others(
    campaign,
) -> None:
    root, _ = campaign
    record = {
        "steps": 1010, "method": "huri", "model": f"{ENV}.zip", "falls": 12, "before_fall_states": 300,
        "risk_before_fall": -0.45, "risk_elsewhere": -0.06,
        "explained_variance": {"value": 0.45, "atom_mean": 0.57},
        "per_rollout": [{"value": 0.40, "atom_mean": 0.52}, {"value": 0.50, "atom_mean": 0.61}],
        "settings": {"rollouts": 2, "robots": 4, "rollout_steps": 8, "pre_fall_steps": 25},
    }  # fmt: skip
    path = root / "huri" / f"{ENV}_1" / "evaluations" / "1010-value_baseline.json"
    path.write_text(json.dumps(record))
    try:
        page = write_results(root / "campaign.yml", root / "docs" / "value.md").read_text()
    finally:
        path.unlink()
    section = page[page.index("## 6d.") :]
    section = section[: section.index("\n## ", 4)]
    cells = _row(section, "huri-s0 @ 0.0M")
    assert cells[1:] == [
        "huri",
        "64",
        "0.450 [0.40, 0.50]",
        "0.570 [0.52, 0.61]",
        "-0.120",
        "-0.45",
        "-0.06",
        "12",
    ]
    assert "ppo-s0: `python -m study.scripts.value_baseline " in section and "--steps 1000`" in section
    headline = page[page.index("## What the numbers show") : page.index("## 1.")]
    assert (
        "atoms' mean on 1 of 1 agents with a quantile critic (value minus atoms' mean -0.120 to -0.120"
        in headline
    )


def test_figures_are_drawn_small_and_linked(campaign) -> None:
    root, _ = campaign
    page = _page(root)
    for name in ("robustness", "returns", "tracking", "risk"):
        figure = root / "docs" / "results" / f"{name}.png"
        assert figure.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
        assert figure.stat().st_size < 200_000
        assert f"![{name}](results/{name}.png)" in page
    assert "reached full scale at 512 steps" in page  # the curriculum's scale, from curve.csv
    assert _row(page, "huri-s0 @ 0.0M", "## 6.")[-1] == "holds (uneven > push > plane)"


def test_a_page_rendered_again_from_unchanged_data_leaves_every_figure_as_it_was(campaign) -> None:
    """The figures carry no version or date and are written only when their bytes change, so a render of
    unchanged data changes no file in git."""
    root, _ = campaign
    figures = sorted((root / "docs" / "results").glob("*.png"))
    before = {path: (path.read_bytes(), path.stat().st_mtime_ns) for path in figures}
    write_results(root / "campaign.yml", root / "docs" / "results.md")
    assert sorted((root / "docs" / "results").glob("*.png")) == figures
    for path, (content, written) in before.items():
        assert path.read_bytes() == content and path.stat().st_mtime_ns == written, path.name
        assert b"matplotlib" not in content, path.name


def test_a_figure_without_data_is_removed(tmp_path: Path) -> None:
    (tmp_path / "preset.yml").write_text("Zerith1-v0: {}\n")
    entry = {"name": "a", "protocol": "robust", "method": "huri", "seed": 0, "run": "r", "conf": "preset.yml"}
    (tmp_path / "campaign.yml").write_text(yaml.safe_dump({"entries": [{**entry, "steps": 10}]}))
    stale = tmp_path / "docs" / "results" / "risk.png"
    stale.parent.mkdir(parents=True)
    stale.write_bytes(b"old")
    page = write_results(tmp_path / "campaign.yml", tmp_path / "docs" / "results.md").read_text()
    assert not stale.exists()
    assert "No risk trace is written yet." in page
    assert "No HuRi-PPO pair is evaluated yet" in page


def _entry(run: Path, steps: int, **defaults: int) -> CampaignEntry:
    conf = run.parent / "preset.yml"
    conf.write_text("Zerith1-v0: {}\n")
    return CampaignEntry("e", "robust", "huri", 0, run, conf, steps, QueueDefaults(**defaults))


def test_find_checkpoint_takes_the_first_complete_model_at_or_after_the_target(tmp_path: Path) -> None:
    run = tmp_path / "run"
    (run / ENV).mkdir(parents=True)
    (run / f"{ENV}.zip").write_bytes(b"newest")
    (run / ENV / "vecnormalize.pkl").write_bytes(b"stats")
    (run / ENV / "state.json").write_text(json.dumps({"timesteps": 5000}))
    kept = run / "checkpoints"
    kept.mkdir()
    for steps in (1000, 2000, 3000):
        (kept / f"rl_model_{steps}_steps.zip").write_bytes(b"model")
    for steps in (1000, 3000):  # 2000's normalizer is missing: a checkpoint cut by a kill
        (kept / f"rl_model_vecnormalize_{steps}_steps.pkl").write_bytes(b"stats")
    assert find_checkpoint(_entry(run, 1000)) == (
        1000,
        kept / "rl_model_1000_steps.zip",
        kept / "rl_model_vecnormalize_1000_steps.pkl",
    )
    assert find_checkpoint(_entry(run, 1500))[0] == 3000
    assert find_checkpoint(_entry(run, 4000)) == (5000, run / f"{ENV}.zip", run / ENV / "vecnormalize.pkl")
    with pytest.raises(ExperimentError, match=r"no saved model at or after 6,000 steps.*1,000, 3,000, 5,000"):
        find_checkpoint(_entry(run, 6000))


@pytest.fixture(scope="module")
def tiny_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A run folder holding an untrained HuRi model (no normalizer) at 16 steps."""
    import zerith_gym
    from sb3_huri import HuRiPPO

    run = tmp_path_factory.mktemp("tiny") / "run"
    (run / ENV).mkdir(parents=True)
    env = zerith_gym.make_vec_env(2, workers=0)
    model = HuRiPPO(
        "MultiInputPolicy", env, n_steps=8, n_quantiles=8, policy_kwargs={"net_arch": [8]}, seed=3
    )
    model.save(run / f"{ENV}.zip")
    env.close()
    session = {"from_timesteps": 0, "to_timesteps": 16, "hardware": "test machine", "started": "-"}
    (run / ENV / "state.json").write_text(json.dumps({"timesteps": 16, "wall_s": 2.0, "sessions": [session]}))
    append_row(run, {**dict.fromkeys(CURVE_COLUMNS, math.nan), "timesteps": 16, "wall_s": 2.0})
    return run


def test_evaluate_entry_writes_every_case_per_robot_and_keeps_the_random_states(tiny_run: Path) -> None:
    entry = _entry(tiny_run, 16, eval_episodes=2, eval_seed=5)
    random.seed(1), np.random.seed(1), th.manual_seed(1)  # noqa: NPY002
    path = evaluate_entry(entry, workers=0, episode_steps=3)
    draws = (random.random(), np.random.random(), th.rand(1).item())  # noqa: NPY002
    random.seed(1), np.random.seed(1), th.manual_seed(1)  # noqa: NPY002
    assert draws == (random.random(), np.random.random(), th.rand(1).item())  # noqa: NPY002
    data = json.loads(path.read_text())
    assert path == tiny_run / "evaluations" / "16.json" and entry.evaluation() == path
    assert (data["entry"], data["steps"], data["wall_s"]) == ("e", 16, 2.0)
    assert data["hardware"] == ["test machine"]
    assert data["settings"] == {"episodes": 2, "seed": 5, "episode_steps": 3}
    assert set(data["cases"]) == set(EVALUATION_CASES)
    for metrics in data["cases"].values():
        assert len(metrics["survived"]) == len(metrics["fall_step"]) == 2 and "domain" not in metrics
        assert metrics["survive"] == np.mean(metrics["survived"])
    for case in RISK_CASES:
        with np.load(trace_path(tiny_run, 16, case)) as trace:
            assert trace["beta"].shape == (3,)
    assert evaluate_entry(entry) == path  # done already: nothing is run again
    other = CampaignEntry("f", "robust", "huri", 0, tiny_run, entry.conf, 10, entry.defaults)
    with pytest.raises(ExperimentError, match="already evaluated for entry e"):
        evaluate_entry(other)
    path.unlink()


class Killed(Exception):
    """The evaluation stopped in the middle of a case."""


def test_an_interrupted_evaluation_continues_with_the_next_case(tiny_run: Path, monkeypatch) -> None:
    entry = _entry(tiny_run, 16, eval_episodes=2, eval_seed=5)
    real, calls, kill_at = record.evaluate, [], [3]

    def evaluate(*args, **kwargs):
        calls.append(args[2])
        if len(calls) in kill_at:
            raise Killed
        return real(*args, **kwargs)

    monkeypatch.setattr(record, "evaluate", evaluate)
    with pytest.raises(Killed):
        evaluate_entry(entry, workers=0, episode_steps=3)
    partial = tiny_run / "evaluations" / "16.json.partial"
    assert len(json.loads(partial.read_text())["cases"]) == 2
    assert (
        entry.evaluation() is None and progress.state(entry) == "evaluate"
    )  # a partial file is not a result
    calls.clear(), kill_at.clear()
    path = evaluate_entry(entry, workers=0, episode_steps=3)
    assert len(calls) == len(EVALUATION_CASES) - 2 and not partial.exists()
    assert set(json.loads(path.read_text())["cases"]) == set(EVALUATION_CASES)
    path.unlink()


def test_the_campaign_queue_loads_with_the_synthetic_presets(campaign) -> None:
    root, _ = campaign
    assert [progress.state(e) for e in load_queue(root / "campaign.yml")] == [
        "done",
        "done",
        "done",
        "train",
        "new",
    ]


def test_the_quadruped_section_draws_return_and_terrain_level_and_table8(tmp_path):
    """Quadruped entries: the Fig. 10 analog from their curves (terrain level included), Table 8 from their
    evaluations, and the humanoid's sections untouched by them."""
    go2 = "Go2Like-v0"
    (tmp_path / "preset.yml").write_text("Go2Like-v0: {}\n")
    entries = []
    names = {"huri": "huri", "huri-baseline": "ppo", "huri-percentile": "percentile"}
    for method in names:
        run = tmp_path / "quadruped-rough" / method / f"{go2}_1"
        (run / go2).mkdir(parents=True)
        state = {"timesteps": 640, "wall_s": 64.0, "sessions": [{"from_timesteps": 0, "hardware": "m"}]}
        (run / go2 / "state.json").write_text(json.dumps(state))
        for step in range(64, 641, 64):
            row = {
                "timesteps": step,
                "wall_s": step / 10,
                "ep_return": step / 100,
                "terrain_level": step / 320,
            }
            append_row(run, {**dict.fromkeys(CURVE_COLUMNS, math.nan), **row})
        name = f"quadruped-rough-{names[method]}-s0"
        entries.append(dict(name=name, protocol="quadruped", method=method, seed=0, conf="preset.yml",
                            run=f"quadruped-rough/{method}/{go2}_1", steps=640))  # fmt: skip
    survived = {
        "huri": {"platform-0.40": [1, 1, 0, 1] * 5, "platform-0.45": [1, 0, 0, 1] * 5, "nominal@1": [1] * 20},
        "huri-baseline": {"platform-0.40": [0, 1, 0, 0] * 5, "platform-0.45": [0, 1, 0, 1] * 5},
        "huri-percentile": {"platform-0.40": [0, 1, 1, 1] * 5, "platform-0.45": [1, 1, 0, 1] * 5},
    }
    for entry in entries:
        cases = {
            c: {"survived": alive, "fall_step": [None] * 20} for c, alive in survived[entry["method"]].items()
        }
        cases.get("nominal@1", {})["vx"] = 0.968
        record = {"entry": entry["name"], "steps": 640, "cases": cases, "settings": {"episodes": 20}}
        (tmp_path / entry["run"] / "evaluations").mkdir()
        (tmp_path / entry["run"] / "evaluations" / "640.json").write_text(json.dumps(record))
    (tmp_path / "campaign.yml").write_text(yaml.safe_dump({"entries": entries}))
    page = write_results(tmp_path / "campaign.yml", tmp_path / "docs" / "results.md").read_text()
    assert "## 7. The quadruped" in page and "quadruped-rough-ppo-s0" in page
    assert (tmp_path / "docs" / "results" / "quadruped.png").stat().st_size > 10_000
    row = next(line for line in page.splitlines() if line.startswith("| [quadruped-rough-huri-s0"))
    assert "| 0.75 [" in row and "| 0.50 [" in row and "| - |" in row  # 0.40 m, 0.45 m, nominal@0.5 missing
    assert row.endswith("| 0.97 | - |")  # forward velocity at 1 m/s; none at 0.5 m/s
    assert "PPO 65%, HuRi 93%" in page  # the paper's Table 8 beside
    status = next(line for line in page.splitlines() if line.startswith("| quadruped-rough-ppo-s0 |"))
    assert "done (evaluated at 640)" in status
    # HuRi minus PPO on the same 20 robots: 0.40 m 15 vs 5 (10 only HuRi, 0 only PPO); 0.45 m 10 vs 10.
    pair = page.split("**quadruped-rough-huri-s0 @ 0.0M minus quadruped-rough-ppo-s0 @ 0.0M**")[1]
    platform40 = next(line for line in pair.splitlines() if line.startswith("| platform-0.40 |"))
    difference, low, high = paired_difference_interval(
        np.array(survived["huri"]["platform-0.40"], bool),
        np.array(survived["huri-baseline"]["platform-0.40"], bool),
    )
    assert (
        f"| 0.75 | 0.25 | {difference:+.3f} [{low:+.3f}, {high:+.3f}] | 10 | 0 | HuRi survives more |"
        in platform40
    )
    platform45 = next(line for line in pair.splitlines() if line.startswith("| platform-0.45 |"))
    assert "| 5 | 5 | the interval includes 0" in platform45
    assert not any(
        line.startswith("| nominal@1 |") for line in pair.split("##")[0].splitlines()
    )  # PPO lacks it
    finding = next(line for line in page.splitlines() if line.startswith("- quadruped-rough-huri-s0 minus"))
    assert (
        "platform-0.40 +0.500 [" in finding and "HuRi survives more" in finding and "One seed (0)" in finding
    )
    # The percentile band beside HuRi against the same PPO, and against HuRi directly: on 0.40 m they
    # disagree on robots 0 (only HuRi) and 2 (only the band) of each four: +0.000.
    side = page.split("**Methods side by side, quadruped protocol, seed 0**")[1]
    assert _row(side, "case")[1:] == [
        "HuRi minus PPO",
        "huri-percentile minus PPO",
        "huri-percentile minus HuRi",
    ]
    assert _row(side, "platform-0.40")[3].startswith("+0.000 [")
    assert _row(side, "platform-0.45")[3].startswith("+0.250 [")  # robot 1 of each four: only the band
    finding = next(line for line in page.splitlines() if line.startswith("- huri-percentile minus HuRi"))
    assert "platform-0.45 +0.250 [" in finding and "quadruped protocol" in finding


def _shape_run(folder: Path, steps: int, ret: float, fall: float, speed: float, rows: dict[int, float]):
    """A run folder whose curve holds a constant return and fall rate, `speed` samples per second, and
    robustness rows at the given steps."""
    (folder / ENV).mkdir(parents=True)
    (folder / ENV / "state.json").write_text(json.dumps({"timesteps": steps, "wall_s": steps / speed}))
    for step in range(0, steps + 1, 100):
        row = {"timesteps": step, "wall_s": step / speed, "ep_return": ret, "fall_rate": fall, "scale": 1.0}
        append_row(folder, {**dict.fromkeys(CURVE_COLUMNS, math.nan), **row})
    lines = ["timesteps,table1_mean,episodes"] + [f"{s},{m},10" for s, m in rows.items()]
    (folder / "robustness.csv").write_text("\n".join(lines) + "\n")


def test_the_rollout_shape_section_holds_each_wide_seed_to_its_32_robot_seed(tmp_path: Path) -> None:
    """`robust-256` runs against the `robust` run of their method and seed: values at every checkpoint,
    the nearest robustness row, samples per second, a t interval over seeds of the return difference, and
    the paired final evaluations where both shapes were evaluated at the same step."""
    (tmp_path / "preset.yml").write_text("Zerith1-v0: {}\n")
    _shape_run(tmp_path / "wide0", 2000, 110.0, 0.10, 10.0, {1000: 0.2, 2000: 0.3})
    _shape_run(tmp_path / "wide1", 2000, 105.0, 0.20, 10.0, {1000: 0.1})
    _shape_run(tmp_path / "ref0", 3000, 100.0, 0.15, 5.0, {900: 0.25, 2100: 0.35, 3000: 0.5})
    _shape_run(tmp_path / "ref1", 2500, 97.0, 0.30, 5.0, {})
    _shape_run(tmp_path / "paper0", 2000, 50.0, 0.5, 5.0, {})
    entries = [
        dict(name=name, protocol=protocol, method="huri", seed=seed, run=run, conf="preset.yml", steps=4000)
        for name, protocol, seed, run in (
            ("wide-s0", "robust-256", 0, "wide0"),
            ("wide-s1", "robust-256", 1, "wide1"),
            ("ref-s0", "robust", 0, "ref0"),
            ("ref-s1", "robust", 1, "ref1"),
            ("paper-s0", "paper", 0, "paper0"),
        )
    ]
    queue = {"defaults": {"robustness_every": 1000}, "entries": entries}
    (tmp_path / "campaign.yml").write_text(yaml.safe_dump(queue))
    rng = np.random.default_rng(3)
    # Seed 1: both shapes evaluated within one rollout (32 samples) of each other on the same robots. Seed 0:
    # at the same step, but on other robots (other evaluation settings): not paired.
    for run in ("wide1", "ref1"):
        (tmp_path / run / ENV / "config.yml").write_text(yaml.safe_dump({"n_envs": 4, "n_steps": 8}))
    wide1 = _evaluation(tmp_path / "wide1", "wide-s1", "huri", 1, 2000, rng)
    ref1 = _evaluation(tmp_path / "ref1", "ref-s1", "huri", 1, 2016, rng)
    _evaluation(tmp_path / "wide0", "wide-s0", "huri", 0, 2000, rng)
    _evaluation(tmp_path / "ref0", "ref-s0", "huri", 0, 2000, rng)
    other_robots = tmp_path / "ref0" / "evaluations" / "2000.json"
    record = json.loads(other_robots.read_text())
    other_robots.write_text(json.dumps({**record, "settings": {**record["settings"], "seed": 3000}}))
    page = write_results(tmp_path / "campaign.yml", tmp_path / "docs" / "results.md").read_text()
    section = page[page.index("## 8. Rollout shape") :]
    assert "One seed so far: an anecdote." in section
    assert section.count("**wide-s1 @ 0.0M minus ref-s1 @ 0.0M** (HuRi, seed 1)") == 1
    assert "wide-s0 @" not in section
    row = next(line for line in section.splitlines() if line.startswith("| sudden-feet |"))
    a, b = wide1["sudden-feet"], ref1["sudden-feet"]
    difference, low, high = paired_difference_interval(a, b)
    assert row.startswith(f"| sudden-feet | {a.mean():.2f} | {b.mean():.2f} | ")
    assert f"| {difference:+.3f} [{low:+.3f}, {high:+.3f}] |" in row
    assert f"| {int(np.sum(a & ~b))} | {int(np.sum(~a & b))} |" in row
    per_robot = np.mean([wide1[c].astype(float) - ref1[c].astype(float) for c in TABLE1_SCENARIOS], axis=0)
    mean_row = next(line for line in section.splitlines() if line.startswith("| Table-1 mean (t over"))
    assert f"| {per_robot.mean():+.3f} [" in mean_row
    table = [line for line in section.splitlines() if line.startswith("| HuRi |")]
    assert table == [
        "| HuRi | 0 | 0.0M | 110.0 | 100.0 | 0.10 | 0.15 | 0.200 | 0.250 |",
        "| HuRi | 0 | 0.0M | 110.0 | 100.0 | 0.10 | 0.15 | 0.300 | 0.350 |",
        "| HuRi | 1 | 0.0M | 105.0 | 97.0 | 0.20 | 0.30 | 0.100 | - |",
        "| HuRi | 1 | 0.0M | 105.0 | 97.0 | 0.20 | 0.30 | - | - |",
    ]
    differences = np.array([10.0, 8.0])
    half = stats.t.ppf(0.975, 1) * differences.std(ddof=1) / math.sqrt(2)
    assert f"+9.0 [{9.0 - half:+.1f}, {9.0 + half:+.1f}]" in section
    assert "no difference in learning per sample measured" in section  # [-3.7, +21.7] holds 0
    assert "`../wide0` 10 samples/s, `../ref0` 5" in section
    assert "paper0" not in section
    assert (tmp_path / "docs" / "results" / "rollout_shape.png").stat().st_size > 10_000


def test_the_page_numbers_its_sections_in_the_order_sections_gives(campaign) -> None:
    """Every numbered heading of the page is one of ``sections.PAGE_ORDER``'s, with its number, in that
    order (a section with nothing to show yet is left out, the others keep their numbers)."""
    from study.results.sections import NUMBERS, PAGE_ORDER

    root, _ = campaign
    numbered = re.findall(r"(?m)^## (\d+[a-z]?)\. ", _page(root))
    order = [NUMBERS[key.lstrip("+")] for key in PAGE_ORDER]
    assert len(numbered) >= 10 and numbered == [number for number in order if number in numbered]
    assert order[:7] == ["1", "2", "3", "4", "5", "6", "6b"] and order[-1] == str(len(NUMBERS) - 3)
