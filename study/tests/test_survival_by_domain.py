"""study.analyses.domain_survival (`study/scripts/survival_by_domain.py`) and
`evaluate(..., per_robot=True)`: which robots fall, by their draws."""

from __future__ import annotations

import numpy as np
import pytest

from sb3_huri.runner.evaluation import HoldStance, evaluate
from study.analyses import domain_survival as survival
from zerith_gym.core.randomization import DOMAIN_VECTOR_SIZE, TEST_FRICTION, DomainParams


def test_each_robot_reports_the_parameters_it_drew() -> None:
    stand = HoldStance()
    test = evaluate(
        stand, None, "sudden-feet", (0.0, 0.0, 0.0), 4, 0, episode_steps=3, workers=0, per_robot=True
    )
    friction = test["domain"].friction[:, 0]
    assert np.all((friction >= TEST_FRICTION[0]) & (friction <= TEST_FRICTION[1]))
    assert len(np.unique(friction)) == 4
    again = evaluate(
        stand, None, "sudden-feet", (0.0, 0.0, 0.0), 2, 2, episode_steps=3, workers=0, per_robot=True
    )
    np.testing.assert_allclose(again["domain"].friction[:, 0], friction[2:], rtol=1e-5)  # robot i: seed + i
    nominal = evaluate(
        stand, None, "nominal", (0.0, 0.0, 0.0), 2, 0, episode_steps=3, workers=0, per_robot=True
    )
    np.testing.assert_allclose(nominal["domain"].friction, 1.0, rtol=1e-5)
    assert "domain" not in evaluate(stand, None, "nominal", None, 1, 0, episode_steps=3, workers=0)


def test_bins_count_every_robot_once_and_hold_their_lower_edge() -> None:
    values = np.array([0.1, 0.3, 0.29, 0.55, 2.0, 1.2])
    survived = np.array([False, True, False, True, True, False])
    cells = survival.survival_per_bin(values, survived, np.array([0.1, 0.3, 0.55, 2.0]))
    assert [n for _, n in cells] == [2, 1, 3]  # 0.3 opens the second bin, 2.0 closes the last
    assert cells[0][0] == 0.0 and cells[1][0] == 1.0 and cells[2][0] == pytest.approx(2 / 3)
    empty = survival.survival_per_bin(values, survived, np.array([5.0, 6.0, 7.0]))
    assert sum(n for _, n in empty) == len(values)  # outliers go to the nearest end bin


def test_correlations_match_numpy_and_skip_what_does_not_vary() -> None:
    rng = np.random.default_rng(0)
    vector = rng.uniform(size=(40, DOMAIN_VECTOR_SIZE))
    vector[:, -1] = 0.02  # the action delay does not vary
    values = survival.scalar_parameters(DomainParams.from_vector(vector))
    assert {"friction", "added_mass", "com_offset_x", "com_offset_z", "kp_scale_mean"} <= set(values)
    np.testing.assert_allclose(values["com_offset_y"], vector[:, 3])
    fell = values["friction"] < 0.4
    correlations = survival.fall_correlations(values, fell)
    assert "action_delay" not in correlations
    expected = np.corrcoef(fell.astype(float), values["friction"])[0, 1]
    assert correlations["friction"][0] == pytest.approx(expected) and correlations["friction"][1] < 1e-3
    assert survival.fall_correlations(values, np.ones(40, dtype=bool)) == {}
