"""The study's scripts (``study/scripts/``), whose work lives in ``study.analyses``, stay working command
lines: each one's imports resolve and its parser answers ``--help`` (their logic is tested through the
analyses)."""

from __future__ import annotations

import runpy
import sys

import pytest

SCRIPTS = (
    "robustness_curve",
    "survival_by_domain",
    "force_exposure",
    "impulse_envelope",
    "eval_agents",
    "compare_agents",
    "expectation_loss",
    "risk_levels",
    "advantages",
    "value_baseline",
    "force_magnitude",
    "asymmetry",
    "stance_floor",
    "mjx_terrain",
)


@pytest.mark.parametrize("script", SCRIPTS)
def test_script_answers_help(script: str, monkeypatch, capsys) -> None:
    monkeypatch.setattr(sys, "argv", [f"study/scripts/{script}.py", "--help"])
    with pytest.raises(SystemExit) as stop:
        runpy.run_module(f"study.scripts.{script}", run_name="__main__")
    assert stop.value.code == 0
    assert capsys.readouterr().out.startswith("usage:")
