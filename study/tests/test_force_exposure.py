"""study.analyses.force_exposure (`study/scripts/force_exposure.py`): robot-steps and falls
counted by the force the scenario's table names."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

import zerith_gym
from sb3_huri.runner.evaluation import HoldStance
from study.analyses.force_exposure import exposure
from zerith_gym.core.disturbances import TARGET_INDEX
from zerith_gym.core.randomization import NOMINAL
from zerith_gym.core.scenarios import SCENARIOS, scaled_scenario


def test_robot_steps_are_counted_under_the_force_of_each_robots_table_step() -> None:
    gentle = replace(scaled_scenario(SCENARIOS["robust"], 0.1), randomization=NOMINAL)  # no robot falls
    env = zerith_gym.make_vec_env(6, seed=1, scenario=gentle, workers=0)
    kinds, steps, falls = exposure(HoldStance(), None, env, 250)
    offsets = env.robots.task.state.force_offset.copy()  # no reset since the first: no robot fell
    env.close()
    continuous, sudden = (0.0, 10.0), (15.0, 20.0)
    targets = ("centroid", "hands", "feet")
    expected_kinds = [(TARGET_INDEX[t], *m) for t in targets for m in (continuous, sudden)]
    np.testing.assert_allclose(kinds, expected_kinds)
    table = gentle.force.table(2000)
    visited = np.concatenate([offset + np.arange(250) for offset in offsets])
    for row, (target, low, high) in enumerate(kinds):
        named = (table.target[visited] == target) & (table.magnitude[visited, 1] == high)
        assert steps[row] == named.sum(), (target, low, high)
    assert steps.sum() == 6 * 250 and not falls.any()

    falling = zerith_gym.make_vec_env(4, seed=1, scenario="robust", workers=0)  # full forces topple them
    kinds, steps, falls = exposure(HoldStance(), None, falling, 300)
    falling.close()
    assert falls.sum() > 0 and steps.sum() == 4 * 300
