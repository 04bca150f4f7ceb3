"""The analyses a campaign entry is measured on after its final evaluation (study.campaign
.analyses): which apply to which entry, the ``measure`` state until their files hold every case, a
measurement cut by the wall time going on where it stopped, and the queue's ``analyses`` default."""

from __future__ import annotations

import json
import time
from pathlib import Path

import pytest
import yaml
from huri_helpers import tiny_robust_preset

from sb3_huri.experiments.errors import ExperimentError
from study.analyses import risk_levels
from study.analyses.advantages import advantages_path
from study.analyses.force_magnitude import HEADLINE, Reading, result_path
from study.analyses.risk_levels import risk_levels_path
from study.campaign import analyses, progress
from study.campaign.progress import run_entry
from study.campaign.queue import ANALYSES, load_queue
from study.campaign.scheduler import runnable

SMALL_PLAN = (
    ((HEADLINE, Reading(per_body=True)), ("continuous-hands",), (0.5, 1.0)),
    ((Reading("nominal"),), ("sudden-centroid",), (1.0,)),
)
"""A force-magnitude plan of five case-scales, in the shape of the real one."""
EPISODE_STEPS = 420
"""Short episodes that still reach the robust scenario's forces (its episodes start 400 steps into them),
the training scenario the risk levels measure."""


def _queue(folder: Path, **defaults) -> Path:
    tiny_robust_preset(folder)
    entries = [
        dict(
            name=name,
            protocol="robust",
            method=method,
            seed=0,
            run=f"{name}/Zerith1-v0_1",
            conf="tiny.yml",
            steps=64,
        )
        for name, method in (("huri-s0", "huri-percentile"), ("ppo-s0", "huri-baseline"))
    ]
    path = folder / "campaign.yml"
    defaults = dict(eval_episodes=2, episode_steps=EPISODE_STEPS, robustness_every=10**6, **defaults)
    path.write_text(yaml.safe_dump({"defaults": defaults, "entries": entries}))
    return path


def test_an_entry_is_measured_after_its_evaluation_and_a_cut_measurement_goes_on(tmp_path, monkeypatch):
    monkeypatch.setattr(analyses, "FORCE_PLAN", SMALL_PLAN)
    huri, ppo = load_queue(_queue(tmp_path))
    assert huri.defaults.analyses == ANALYSES
    assert analyses.applies("risk_levels", huri) and not analyses.applies("risk_levels", ppo)
    assert analyses.applies("force_magnitude", ppo) and analyses.pending(huri) == []  # not evaluated yet
    assert analyses.applies("advantages", huri) and not analyses.applies("advantages", ppo)

    # Trained, evaluated, then measured at the evaluated checkpoint: done.
    assert run_entry(huri, workers=0) == "done" and analyses.pending(huri) == []
    risk = json.loads(risk_levels_path(huri.run, 64).read_text())
    assert risk["steps"] == 64 and len(risk["cases"]) >= 4
    assert set(risk["cases"]) == risk_levels.measured_cases(risk)  # the falls' statistics too
    assert risk["settings"]["episode_steps"] == EPISODE_STEPS
    assert json.loads(advantages_path(huri.run, 64).read_text())["steps"] == 64
    force = json.loads(result_path(huri.run, 64).read_text())
    measured = {key: {case: sorted(scales) for case, scales in cases.items()}
                for key, cases in force["measurements"].items()}  # fmt: skip
    assert measured == {
        "test:pair:hold5": {"continuous-hands": ["0.5", "1"]},
        "test:per-body:hold5": {"continuous-hands": ["0.5", "1"]},
        "nominal:pair:hold5": {"sudden-centroid": ["1"]},
    }

    # Files that lost cases make the entry `measure` again; past its deadline nothing starts.
    risk_levels_path(huri.run, 64).unlink()
    kept = force["measurements"]["test:pair:hold5"]["continuous-hands"]["0.5"]
    del force["measurements"]["test:per-body:hold5"]["continuous-hands"]["1"]
    result_path(huri.run, 64).write_text(json.dumps(force))
    assert progress.state(huri) == "measure" and analyses.pending(huri) == ["risk_levels", "force_magnitude"]
    assert analyses.measure(huri, deadline=time.time() - 1) == ["risk_levels", "force_magnitude"]
    assert not risk_levels_path(huri.run, 64).exists()

    # The next call measures what is missing only, and keeps what was there.
    assert analyses.measure(huri) == [] and progress.state(huri) == "done"
    again = json.loads(result_path(huri.run, 64).read_text())["measurements"]
    assert again["test:pair:hold5"]["continuous-hands"]["0.5"] == kept
    assert "1" in again["test:per-body:hold5"]["continuous-hands"]
    assert risk_levels_path(huri.run, 64).is_file()

    # An analysis that fails leaves the others to run, then says why.
    def broken(*args, **kwargs):
        raise ExperimentError("the critic cannot be read")

    risk_levels_path(huri.run, 64).unlink()
    del again["test:pair:hold5"]["continuous-hands"]["1"]
    result_path(huri.run, 64).write_text(json.dumps({**force, "measurements": again}))
    monkeypatch.setattr(risk_levels, "measure_risk_levels", broken)
    with pytest.raises(ExperimentError, match="huri-s0: risk_levels: the critic cannot be read"):
        analyses.measure(huri)
    assert (
        "1"
        in json.loads(result_path(huri.run, 64).read_text())["measurements"]["test:pair:hold5"][
            "continuous-hands"
        ]
    )
    assert analyses.pending(huri) == ["risk_levels"]

    # PPO has no quantile critic: its force magnitude only.
    assert run_entry(ppo, workers=0) == "done"
    assert result_path(ppo.run, 64).is_file() and not risk_levels_path(ppo.run, 64).exists()
    assert not advantages_path(ppo.run, 64).exists()


def test_a_queue_without_analyses_is_done_at_its_evaluation(tmp_path):
    (entry, _) = load_queue(_queue(tmp_path, analyses=[]))
    assert run_entry(entry, workers=0) == "done"
    assert not list((entry.run / "evaluations").glob("*-*.json"))


@pytest.mark.parametrize("value", [["risk"], "force_magnitude", {"a": 1}, [{"risk_levels": 1}]])
def test_the_queues_analyses_name_known_ones(tmp_path, value):
    with pytest.raises(ExperimentError, match="analyses:` is a list of risk_levels, force_magnitude"):
        load_queue(_queue(tmp_path, analyses=value))


def test_an_entry_whose_analyses_failed_does_not_hold_its_run_folder_back(tmp_path):
    """Trained and evaluated, its analyses failing: the next entry of its run folder may train on (a failed
    training or evaluation holds it back: tests/test_campaign.py)."""
    tiny_robust_preset(tmp_path)
    entry = dict(protocol="robust", method="huri", seed=0, run="a/Zerith1-v0_1", conf="tiny.yml")
    queue = tmp_path / "campaign.yml"
    entries = [{**entry, "name": "a-first", "steps": 100}, {**entry, "name": "a-later", "steps": 200}]
    queue.write_text(yaml.safe_dump({"entries": entries}))
    run = tmp_path / "a" / "Zerith1-v0_1"
    (run / "Zerith1-v0").mkdir(parents=True)
    (run / "Zerith1-v0" / "state.json").write_text('{"timesteps": 100, "wall_s": 0, "sessions": []}')
    (run / "Zerith1-v0.zip").write_bytes(b"the model at 100 steps")
    (run / "evaluations").mkdir()
    (run / "evaluations" / "100.json").write_text('{"entry": "a-first"}')
    first, later = load_queue(queue)
    assert progress.state(first) == "measure" and analyses.pending(first) == list(ANALYSES)
    assert [e.name for e in runnable([first, later], busy=set(), failed=set())] == ["a-first"]
    assert [e.name for e in runnable([first, later], busy=set(), failed={"a-first"})] == ["a-later"]
