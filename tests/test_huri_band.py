"""The IQR band's two readings: the absolute band (the paper's thresholds in units of the normalized
return) and the percentile band (thresholds that follow the critic's own IQR, so that the levels do not
depend on the return's scale); the band's levels on the rollout they come from, frozen outside training,
saved and loaded."""

import json
import zipfile

import numpy as np
import pytest
import torch as th
from huri_helpers import SMALL, KeyRecorder, dict_env
from stable_baselines3.common.logger import Logger

from sb3_huri import METHODS, HuRiPPO
from sb3_huri.common.quantiles import interquartile_range
from sb3_huri.huri.risk import RiskModel
from sb3_huri.runner.curve import RISK_COLUMNS, read_curve
from sb3_huri.zoo import method_class

pytestmark = pytest.mark.filterwarnings("ignore::sb3_huri.UnnormalizedRewardWarning")


def risk_of(method: str = "huri-percentile", **arguments) -> RiskModel:
    return HuRiPPO("MlpPolicy", None, method=method, _init_setup_model=False, **arguments).risk_model


def spread_atoms(n_states: int = 500, n_quantiles: int = 64, seed: int = 0) -> th.Tensor:
    """Atoms of `n_states` normal return distributions whose spreads vary over two orders of magnitude."""
    generator = th.Generator().manual_seed(seed)
    levels = (th.arange(n_quantiles, dtype=th.float64) + 0.5) / n_quantiles
    standard = th.distributions.Normal(0.0, 1.0).icdf(levels)
    means = th.randn(n_states, 1, generator=generator, dtype=th.float64)
    spreads = th.exp(th.empty(n_states, 1, dtype=th.float64).uniform_(-2.3, 2.3, generator=generator))
    return means + spreads * standard


def levels_after_band(model: RiskModel, atoms: th.Tensor) -> np.ndarray:
    """The IQR part of the risk level each state gets once the band was read off these same states."""
    banded = model.with_band_from(interquartile_range(atoms).numpy(), first=True)
    return banded.assess(atoms, None).risk_iqr.numpy()


def test_the_percentile_band_gives_the_same_levels_when_the_returns_are_100_times_larger():
    percentile, absolute = risk_of("huri-percentile"), risk_of("huri")
    atoms = spread_atoms()
    small, large = levels_after_band(percentile, atoms), levels_after_band(percentile, 100.0 * atoms)
    np.testing.assert_array_equal(small, large)
    assert {-1.0, 0.0, 1.0} <= set(small.tolist())  # all three levels in use
    # The absolute band reads the same states differently at another scale: averse almost everywhere.
    absolute_small, absolute_large = (
        levels_after_band(absolute, atoms),
        levels_after_band(absolute, 100 * atoms),
    )
    assert (absolute_small != absolute_large).mean() > 0.3
    assert (absolute_large == 1.0).mean() > 0.9


def test_the_band_splits_a_rollout_at_its_percentiles_and_smooths_over_rollouts():
    model = risk_of("huri-percentile", iqr_percentiles=(20, 90), iqr_band_smoothing=0.25)
    iqr = np.random.default_rng(0).gamma(2.0, 0.1, size=10_000)
    first = model.with_band_from(iqr, first=True)
    np.testing.assert_allclose(first.iqr_thresholds, np.percentile(iqr, [20, 90]))
    later = first.with_band_from(3.0 * iqr, first=False)
    expected = 0.75 * np.percentile(iqr, [20, 90]) + 0.25 * np.percentile(3.0 * iqr, [20, 90])
    np.testing.assert_allclose(later.iqr_thresholds, expected)
    assert later.iqr_percentiles == (20.0, 90.0) and later.iqr_band == "percentile"


@pytest.mark.parametrize("method", ["huri", "huri-no-rnd", "huri-cvar", "huri-cvar0.5", "huri-baseline"])
def test_the_absolute_band_and_the_methods_without_a_band_never_move(method):
    model = risk_of(method)
    assert not model.adapts_band
    assert model.with_band_from(np.linspace(0.0, 5.0, 100), first=True) is model


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        (
            dict(iqr_band="relative"),
            r"Unknown iqr_band 'relative': expected one of \['absolute', 'percentile'\]",
        ),
        (dict(iqr_percentiles=(70, 30)), r"iqr_percentiles must be \(p_min, p_max\) with 0 <= p_min"),
        (dict(iqr_percentiles=(30, 170)), "iqr_percentiles"),
        (dict(iqr_band_smoothing=0.0), r"iqr_band_smoothing must be in \(0, 1\], got 0.0"),
        (dict(method="huri-baseline", iqr_band="percentile"), "need a quantile critic"),
    ],
)
def test_bad_band_settings_raise_value_errors_saying_what_is_allowed(kwargs, message):
    with pytest.raises(ValueError, match=message):
        risk_of(**{"method": "huri-percentile", **kwargs})


def test_the_shares_logged_for_a_rollout_match_the_band_read_off_that_rollout():
    """With a smoothing of 1 the band is each rollout's own 30th and 70th IQR percentiles: the states the
    rollout stored split 30 / 40 / 30 between the levels, and the logged shares say so."""
    model = HuRiPPO(
        "MlpPolicy", dict_env(n_envs=4), method="huri-percentile", iqr_band_smoothing=1.0, seed=0, **SMALL
    )
    recorder = KeyRecorder()
    model.set_logger(Logger(folder=None, output_formats=[recorder]))
    model.learn(4 * 32 * 3)
    buffer = model.rollout_buffer
    iqr = interquartile_range(th.as_tensor(buffer.atoms)).numpy().ravel()
    t_min, t_max = model.risk_model.iqr_thresholds
    np.testing.assert_allclose((t_min, t_max), np.percentile(iqr, [30, 70]))
    logged = {key: values[-1] for key, values in recorder.records.items()}  # the last rollout's
    below, within, above = (
        float(np.mean(share)) for share in (iqr < t_min, (iqr >= t_min) & (iqr <= t_max), iqr > t_max)
    )
    assert logged["rollout/iqr_below_share"] == pytest.approx(below)
    assert logged["rollout/iqr_within_share"] == pytest.approx(within)
    assert logged["rollout/iqr_above_share"] == pytest.approx(above)
    assert below == pytest.approx(0.3, abs=0.02) and above == pytest.approx(0.3, abs=0.02)
    # The buffer's risk levels are the band's: -1 below, 0 within, +1 above, plus the RND part.
    risk_iqr = buffer.risk.ravel() - np.tanh(buffer.rnd_error.ravel())
    np.testing.assert_allclose(
        risk_iqr, np.where(iqr > t_max, 1.0, np.where(iqr < t_min, -1.0, 0.0)), atol=1e-5
    )
    assert (logged["rollout/iqr_t_min"], logged["rollout/iqr_t_max"]) == (t_min, t_max)
    assert model.iqr_band_rollouts == 3


def test_the_band_is_frozen_outside_training_and_saved_with_the_model(tmp_path):
    model = HuRiPPO("MlpPolicy", dict_env(), method="huri-percentile", seed=0, **SMALL).learn(128)
    band, rollouts = model.risk_model.iqr_thresholds, model.iqr_band_rollouts
    assert band != (0.3, 0.7) and rollouts == 2
    obs = dict_env(seed=3).reset()
    for _ in range(3):
        model.assess_risk(obs)
        model.predict(obs, deterministic=True)
    assert model.risk_model.iqr_thresholds == band
    model.save(tmp_path / "model.zip")
    loaded = HuRiPPO.load(tmp_path / "model.zip")
    assert loaded.risk_model == model.risk_model and loaded.iqr_band_rollouts == rollouts
    np.testing.assert_array_equal(loaded.assess_risk(obs).risk, model.assess_risk(obs).risk)
    # Training on moves the loaded band on from the saved one (a smoothed step, not a fresh start).
    loaded.set_env(dict_env(seed=1))
    loaded.learn(64, reset_num_timesteps=False)
    assert loaded.iqr_band_rollouts == rollouts + 1 and loaded.risk_model.iqr_thresholds != band


@pytest.mark.parametrize("algorithm", [HuRiPPO, method_class("huri-percentile")])
def test_a_save_from_before_the_band_had_a_reading_loads_with_the_absolute_band(tmp_path, algorithm):
    """A model saved before ``iqr_band`` existed holds no such attribute: it loads with its method's band
    (every method then read the band as absolute), whatever the loading class's default method."""
    HuRiPPO("MlpPolicy", dict_env(), method="huri", **SMALL).save(tmp_path / "new.zip")
    with (
        zipfile.ZipFile(tmp_path / "new.zip") as source,
        zipfile.ZipFile(tmp_path / "old.zip", "w") as target,
    ):
        for item in source.infolist():
            content = source.read(item.filename)
            if item.filename == "data":
                data = json.loads(content)
                saved = ("iqr_band", "iqr_percentiles", "iqr_band_smoothing", "iqr_band_rollouts", "td_level")
                for key in saved:
                    del data[key]
                content = json.dumps(data).encode()
            target.writestr(item, content)
    loaded = algorithm.load(tmp_path / "old.zip")
    assert loaded.method == "huri" and loaded.risk_model.iqr_band == "absolute"
    assert loaded.risk_model == risk_of("huri")


def test_the_percentile_method_is_huri_with_the_percentile_band():
    assert METHODS["huri-percentile"].iqr_band == "percentile"
    assert risk_of("huri-percentile") == risk_of("huri", iqr_band="percentile")


def test_a_campaign_curve_keeps_the_risk_levels_of_each_rollout(tmp_path):
    from sb3_huri.runner.curve import CurveWriter

    class Curve(CurveWriter):
        wall_s = 0.0

    model = HuRiPPO("MlpPolicy", dict_env(), method="huri-percentile", seed=0, **SMALL)
    model.learn(128, callback=Curve(tmp_path))
    rows = read_curve(tmp_path)
    assert len(rows) == 2
    for row in rows:
        shares = [row[column] for column in ("iqr_below", "iqr_within", "iqr_above")]
        assert sum(shares) == pytest.approx(1.0, abs=1e-5)
        assert row["iqr_t_min"] <= row["iqr_t_max"]
        assert all(np.isfinite(row[column]) for column in RISK_COLUMNS)
    assert (rows[-1]["iqr_t_min"], rows[-1]["iqr_t_max"]) == pytest.approx(
        model.risk_model.iqr_thresholds, rel=1e-5
    )
