"""study.analyses.impulses (`study/scripts/impulse_envelope.py`): one push where and when it
is asked for, and Table 1's pushes counted."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from sb3_huri.runner.evaluation import HoldStance, evaluate
from study.analyses import impulses as envelope
from zerith_gym.core.randomization import NOMINAL
from zerith_gym.core.scenarios import SCENARIOS


def test_a_standing_robot_bears_a_light_push_and_falls_only_after_a_hard_one() -> None:
    stand = HoldStance()

    def survive(force: float, after: int, step: int = 100) -> float:
        scenario = envelope.push("centroid", force, math.pi / 2, step, test_ranges=False)
        result = evaluate(stand, None, scenario, (0.0, 0.0, 0.0), 2, 0, episode_steps=step + after, workers=0)
        return result["survive"]

    assert survive(20.0, after=100) == 1.0
    assert survive(2000.0, after=100) == 0.0
    # the push comes at its step, not before: the robots fall after it, and an episode that ends before
    # it survives the same push
    scenario = envelope.push("centroid", 2000.0, math.pi / 2, 150, test_ranges=False)
    fall_step = evaluate(
        stand, None, scenario, (0.0, 0.0, 0.0), 2, 0, episode_steps=250, workers=0, per_robot=True
    )["fall_step"]
    assert np.all((fall_step >= 150) & (fall_step < 250))
    assert (
        evaluate(stand, None, scenario, (0.0, 0.0, 0.0), 2, 0, episode_steps=140, workers=0)["survive"] == 1.0
    )


def test_table1_pushes_account_for_every_robot() -> None:
    robots = 3
    scenario = replace(SCENARIOS["sudden-hands"], randomization=NOMINAL)
    counts = envelope.falls_per_push(HoldStance(), None, scenario, robots, 0)
    standing, fell = counts[:, 0], counts[:, 1]
    assert len(counts) == 9  # a push every 2 s from 2 s on, in 20 s
    assert np.all(standing[1:] == standing[:-1] - fell[:-1])
    assert standing[0] == robots  # the nominal robot stands until the first push
    assert fell.sum() == robots  # and only holding its stance, it falls under Table 1's hand pushes
