"""The benchmark scripts whose work lives in `sb3_huri.experiments` stay working command lines: each one's
imports resolve and its parser answers `--help` (their logic is tested through the package)."""

from __future__ import annotations

import runpy
import sys

import pytest
from huri_helpers import ROOT

SCRIPTS = (
    "robustness_curve.py",
    "survival_by_domain.py",
    "force_exposure.py",
    "impulse_envelope.py",
    "eval_agents.py",
    "compare_agents.py",
    "bench_expectation_loss.py",
)


@pytest.mark.parametrize("script", SCRIPTS)
def test_script_answers_help(script: str, monkeypatch, capsys) -> None:
    monkeypatch.setattr(sys, "argv", [script, "--help"])
    with pytest.raises(SystemExit) as stop:
        runpy.run_path(str(ROOT / "benchmarks" / script), run_name="__main__")
    assert stop.value.code == 0
    assert capsys.readouterr().out.startswith("usage:")
