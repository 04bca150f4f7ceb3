"""HuRiPPO's risk model: built once from the flat arguments, checked in one place, computing the risk level,
logged under names true for Wang and CVaR, and rebuilt exactly when a model is loaded."""

import json
import math
import zipfile

import numpy as np
import pytest
import torch as th
from huri_helpers import ROOT, SMALL, KeyRecorder, dict_env, state_dicts_equal
from stable_baselines3.common.logger import Logger

from sb3_huri import METHODS, HuRiPPO
from sb3_huri.huri import method_of_saved
from sb3_huri.huri.risk import WANG_LOG_KEYS, RiskModel, RiskReading
from sb3_huri.zoo import method_class

pytestmark = pytest.mark.filterwarnings("ignore::sb3_huri.UnnormalizedRewardWarning")


def risk_of(method: str = "huri", **arguments) -> RiskModel:
    """The risk model of ``HuRiPPO(method=method, **arguments)`` (HuRiPPO's defaults for the others)."""
    return HuRiPPO("MlpPolicy", None, method=method, _init_setup_model=False, **arguments).risk_model


# --- building and checking --------------------------------------------------------------------------


@pytest.mark.parametrize("method", list(METHODS))
def test_the_defaults_take_the_methods_preset_and_the_distortions_levels(method):
    risk = risk_of(method)
    preset = METHODS[method]
    assert (risk.distributional, risk.distortion, risk.use_iqr, risk.use_rnd) == (
        preset.distributional,
        preset.distortion,
        preset.use_iqr,
        preset.use_rnd,
    )
    assert risk.n_quantiles == (64 if preset.distributional else 1)
    assert risk.iqr_risk_levels == {"wang": (-1.0, 0.0, 1.0), "cvar": (1.0, 1.0, 0.5)}[risk.distortion]
    assert risk.fixed_level == {"wang": 0.0, "cvar": 0.5}[risk.distortion]


def test_arguments_override_the_preset_and_settings_are_stored_as_floats_and_tuples():
    risk = risk_of(
        "huri", distortion="cvar", use_rnd=False, n_quantiles=16, iqr_thresholds=[0, 2], cvar_alpha=1
    )
    assert (risk.distortion, risk.use_iqr, risk.use_rnd, risk.n_quantiles) == ("cvar", True, False, 16)
    assert risk.iqr_thresholds == (0.0, 2.0) and risk.iqr_risk_levels == (1.0, 1.0, 0.5)
    assert isinstance(risk.cvar_alpha, float)
    # A loaded model's settings are lists: the same settings give an equal model.
    as_loaded = {**risk.settings(), "iqr_thresholds": [0.0, 2.0], "iqr_risk_levels": [1, 1, 0.5]}
    assert RiskModel(**as_loaded) == risk


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        (dict(method="huri-lite"), r"Unknown method 'huri-lite': expected one of \['huri-baseline', "),
        (dict(method="baseline"), "Unknown method 'baseline'"),  # the name before it was huri-baseline
        (dict(distortion="exponential"), "Unknown distortion 'exponential'"),
        (dict(method="huri-baseline", use_iqr=True), "need a quantile critic: method='huri-baseline'"),
        (dict(method="huri-baseline", distortion="cvar"), "need a quantile critic"),
        (dict(use_rnd="yes"), "use_rnd must be True or False, got 'yes'"),
        (dict(n_quantiles=1), r"n_quantiles must be an integer >= 2, got 1"),
        (dict(n_quantiles=8.0), r"n_quantiles must be an integer >= 2"),
        (dict(cvar_alpha=0.0), r"cvar_alpha must be in \(0, 1\], got 0.0"),
        (dict(cvar_alpha="half"), r"cvar_alpha must be in \(0, 1\]"),
        (dict(wang_beta=math.nan), "wang_beta must be a finite number"),
        (dict(wang_beta=math.inf), "wang_beta must be a finite number"),
        (dict(iqr_thresholds=(0.7, 0.3)), r"iqr_thresholds must be \(t_min, t_max\) with 0 <= t_min"),
        (dict(iqr_thresholds=(-0.1, 0.3)), "iqr_thresholds"),
        (dict(iqr_thresholds=(0.3,)), "iqr_thresholds"),
        (dict(iqr_risk_levels=(1.0, 0.0)), r"iqr_risk_levels must be 3 numbers \(below, within, above\)"),
        (dict(iqr_risk_levels="abc"), "iqr_risk_levels"),
    ],
)
def test_bad_risk_settings_raise_value_errors_saying_what_is_allowed(kwargs, message):
    with pytest.raises(ValueError, match=message):
        HuRiPPO("MlpPolicy", "Pendulum-v1", n_steps=64, **kwargs)


def test_a_scalar_critic_takes_no_risk():
    baseline = risk_of("huri-baseline", n_quantiles=16)
    assert baseline.n_quantiles == 1  # the argument is ignored, as HuRiPPO documents
    with pytest.raises(ValueError, match="scalar critic"):
        RiskModel(**{**baseline.settings(), "use_rnd": True})
    with pytest.raises(ValueError, match="scalar critic"):
        RiskModel(**{**baseline.settings(), "n_quantiles": 64})


# --- the risk level ---------------------------------------------------------------------------------


def test_assess_adds_the_iqr_bands_level_and_the_novelty_and_clips_cvar_to_one():
    atoms = th.tensor([[0.0, 0.0, 0.0, 0.0], [0.0, 1.0, 2.0, 3.0]])  # IQR 0 and 2
    novelty = th.tensor([0.5, 0.5])
    wang = risk_of("huri", n_quantiles=4, iqr_thresholds=(0.3, 0.7)).assess(atoms, novelty)
    np.testing.assert_allclose(wang.risk_iqr, [-1.0, 1.0])
    np.testing.assert_allclose(wang.risk, [-1.0 + math.tanh(0.5), 1.0 + math.tanh(0.5)], rtol=1e-6)
    cvar = risk_of("huri-cvar", n_quantiles=4).assess(atoms, novelty)
    np.testing.assert_allclose(cvar.risk, [1.0, 0.5 + math.tanh(0.5)], rtol=1e-6)
    fixed = risk_of("huri-no-rnd", use_iqr=False, wang_beta=0.25, n_quantiles=4)
    reading = fixed.assess(atoms.flip(-1), None)
    np.testing.assert_array_equal(reading.atoms, atoms)  # sorted
    np.testing.assert_allclose(reading.risk, [0.25, 0.25])
    np.testing.assert_array_equal(reading.risk_rnd, [0.0, 0.0])
    np.testing.assert_allclose(reading.value, (reading.weights * atoms).sum(-1))


def test_rollout_metrics_name_the_risk_level_for_both_distortions_and_keep_the_beta_names_for_wang():
    atoms = th.tensor([[0.0, 0.0, 0.0, 0.0], [0.0, 1.0, 2.0, 3.0], [0.0, 0.1, 0.3, 0.5]])
    novelty = th.tensor([0.1, 0.2, 0.3])
    for method in ("huri", "huri-cvar", "huri-cvar0.5"):
        risk = risk_of(method, n_quantiles=4)
        reading = RiskReading(*(tensor.numpy() for tensor in risk.assess(atoms, novelty)))
        metrics = risk.rollout_metrics(reading)
        assert metrics["rollout/risk_mean"] == pytest.approx(float(reading.risk.mean()))
        shares = [metrics[f"rollout/iqr_{side}_share"] for side in ("above", "within", "below")]
        assert shares == pytest.approx([1 / 3, 1 / 3, 1 / 3])
        assert ("rollout/risk_rnd_mean" in metrics) == risk.use_rnd
        legacy = {key for key in metrics if key.startswith("rollout/beta")}
        if risk.distortion == "wang":
            assert legacy == {WANG_LOG_KEYS[key] for key in metrics if key in WANG_LOG_KEYS}
            assert all(metrics[WANG_LOG_KEYS[key]] == metrics[key] for key in metrics if key in WANG_LOG_KEYS)
        else:
            assert not legacy  # the CVaR level is alpha, not beta


def test_a_cvar_run_logs_its_level_under_the_neutral_names_only():
    model = HuRiPPO("MlpPolicy", dict_env(), method="huri-cvar", seed=0, **SMALL)
    recorder = KeyRecorder()
    model.set_logger(Logger(folder=None, output_formats=[recorder]))
    model.learn(64)
    expected = {"rollout/risk_mean", "rollout/risk_iqr_mean", "rollout/risk_rnd_mean", "rollout/iqr_mean"}
    assert expected <= recorder.records.keys()
    assert not [key for key in recorder.records if key.startswith("rollout/beta")]
    assert 0.0 < recorder.records["rollout/risk_mean"][-1] <= 1.0


# --- save and load ----------------------------------------------------------------------------------


@pytest.mark.parametrize(
    "kwargs",
    [
        dict(method="huri-cvar0.5", cvar_alpha=0.3),
        dict(method="huri", distortion="cvar", use_rnd=False, iqr_thresholds=(0.1, 0.4)),
        dict(method="huri-no-iqr", wang_beta=0.5, n_quantiles=16),
    ],
    ids=["huri-cvar0.5", "cvar-without-rnd", "fixed-wang-beta"],
)
def test_a_loaded_model_has_the_saved_risk_model_and_continues_exactly(tmp_path, kwargs):
    model = HuRiPPO("MlpPolicy", dict_env(), seed=0, **kwargs, **SMALL).learn(64)
    model.save(tmp_path / "model.zip")
    # `load` builds the model with the default arguments (method "huri") before restoring the saved ones.
    loaded = HuRiPPO.load(tmp_path / "model.zip")
    assert loaded.risk_model == model.risk_model != risk_of("huri", n_quantiles=16)
    assert loaded.method == model.method
    assert (loaded.distortion, loaded.cvar_alpha) == (model.distortion, model.cvar_alpha)
    obs = dict_env().reset()
    np.testing.assert_array_equal(loaded.assess_risk(obs).value, model.assess_risk(obs).value)
    for each in (model, loaded):
        each.set_env(dict_env(seed=1))
        each.set_random_seed(1)
        each.learn(64, reset_num_timesteps=False)
    state_dicts_equal(loaded.policy.state_dict(), model.policy.state_dict())


def test_settings_given_to_load_rebuild_the_risk_model_and_are_checked(tmp_path):
    HuRiPPO("MlpPolicy", dict_env(), method="huri-cvar0.5", **SMALL).save(tmp_path / "model.zip")
    loaded = HuRiPPO.load(tmp_path / "model.zip", cvar_alpha=0.2)
    assert loaded.risk_model.cvar_alpha == loaded.cvar_alpha == 0.2
    with pytest.raises(ValueError, match="cvar_alpha"):
        HuRiPPO.load(tmp_path / "model.zip", cvar_alpha=2.0)


@pytest.mark.parametrize("method", ["huri", "huri-baseline"])
def test_shipped_agents_load_with_their_methods_risk_model(method):
    path = ROOT / "trained_agents" / method / "Zerith1-v0_1" / "Zerith1-v0.zip"
    if not path.is_file():
        pytest.skip(f"{path} is not there")
    model = HuRiPPO.load(path, device="cpu")
    assert model.method == method and model.risk_model == risk_of(method)


def test_a_saved_variant_is_read_as_its_method_under_todays_name():
    assert method_of_saved({"variant": "baseline", "method": "huri"}) == "huri-baseline"
    assert method_of_saved({"variant": "cvar0.5"}) == "huri-cvar0.5"
    kept = [method for method in METHODS if method not in ("huri-baseline", "huri-cvar0.5")]
    assert [method_of_saved({"variant": method}) for method in kept] == kept
    assert method_of_saved({"method": "huri-no-rnd"}) == "huri-no-rnd"
    assert method_of_saved({}) is None  # a model of SB3's own PPO


def test_a_checkpoint_saved_with_a_variant_loads_with_its_method_and_saves_it(tmp_path):
    """The shipped PPO baseline was saved when HuRiPPO took `variant="baseline"`, which its zip holds."""
    path = ROOT / "trained_agents" / "huri-baseline" / "Zerith1-v0_1" / "Zerith1-v0.zip"
    saved = json.loads(zipfile.ZipFile(path).read("data"))
    assert saved["variant"] == "baseline" and "method" not in saved
    for algorithm in (HuRiPPO, method_class("huri-baseline"), method_class("huri-cvar0.5")):
        model = algorithm.load(path, device="cpu")
        assert model.method == "huri-baseline" and "variant" not in vars(model)
        assert model.risk_model == risk_of("huri-baseline")
    model.save(tmp_path / "model.zip")
    saved = json.loads(zipfile.ZipFile(tmp_path / "model.zip").read("data"))
    assert saved["method"] == "huri-baseline" and "variant" not in saved
    assert HuRiPPO.load(tmp_path / "model.zip", device="cpu").method == "huri-baseline"
