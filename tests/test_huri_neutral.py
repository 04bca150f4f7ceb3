"""``huri-neutral``: every HuRi method's quantile critic with a risk-neutral value (beta fixed at 0, no IQR
band, no RND), the run that separates the quantile critic from the risk distortion.

Its advantages are checked against a GAE written in the tests (``huri_helpers.gae``) on the plain mean of
the rollout's atoms, time-outs included; its weights must be exactly uniform and its distorted expectation
loss (eq. 5 as printed) zero.
"""

import numpy as np
import pytest
import torch as th
from huri_helpers import gae
from stable_baselines3.common.env_util import make_vec_env

from sb3_huri import METHODS, HuRiPPO
from sb3_huri.common.expectation import expectation_loss
from sb3_huri.zoo import method_class

N_QUANTILES = 16


@pytest.fixture(scope="module")
def collected() -> tuple[HuRiPPO, np.ndarray, np.ndarray]:
    """A huri-neutral model after one rollout of 2 Pendulums in 50-step episodes (time-outs inside the
    rollout), with the sorted atoms of the states after it and whether each env's last step ended."""
    env = make_vec_env("Pendulum-v1", n_envs=2, seed=3, env_kwargs=dict(max_episode_steps=50))
    model = HuRiPPO(
        "MlpPolicy", env, method="huri-neutral", n_steps=128, n_quantiles=N_QUANTILES, seed=0, device="cpu",
        policy_kwargs=dict(net_arch=[32, 32]),
    )  # fmt: skip
    _, callback = model._setup_learn(model.n_steps * env.num_envs, callback=None)
    model.collect_rollouts(model.env, callback, model.rollout_buffer, model.n_steps)
    with th.no_grad():
        obs = model.policy.obs_to_tensor(model._last_obs)[0]
        last_atoms = th.sort(model.policy.predict_values(obs), dim=-1).values.numpy()
    return model, last_atoms, model._last_episode_starts.astype(np.float32)


def test_it_is_the_quantile_critic_with_no_risk_machinery() -> None:
    preset = METHODS["huri-neutral"]
    assert preset.distributional and not preset.use_iqr and not preset.use_rnd
    model = method_class("huri-neutral")("MlpPolicy", "Pendulum-v1", n_steps=8, device="cpu")
    assert model.method == "huri-neutral" and model.policy.rnd is None
    assert model.risk_model.risk_neutral and model.risk_model.wang_beta == 0.0
    # Every risk-taking method is not neutral, nor is a scalar critic.
    assert not any(model_of.risk_neutral for model_of in (
        HuRiPPO("MlpPolicy", None, method=name, _init_setup_model=False).risk_model
        for name in METHODS if name != "huri-neutral"
    ))  # fmt: skip
    # A fixed level other than 0 is a fixed-beta Wang distortion, no longer neutral.
    averse = HuRiPPO("MlpPolicy", None, method="huri-neutral", wang_beta=0.5, _init_setup_model=False)
    assert not averse.risk_model.risk_neutral


def test_its_weights_are_uniform_and_its_risk_zero(collected) -> None:
    model, _, _ = collected
    buffer = model.rollout_buffer
    assert buffer.has_time_outs
    np.testing.assert_array_equal(buffer.distortion_weights, np.float32(1.0 / N_QUANTILES))
    np.testing.assert_array_equal(buffer.last_weights, np.float32(1.0 / N_QUANTILES))
    np.testing.assert_array_equal(buffer.risk, 0.0)
    assessed = model.assess_risk(buffer.observations[0])
    np.testing.assert_allclose(assessed.value, assessed.atoms.mean(axis=-1), rtol=1e-6, atol=1e-6)


def test_its_advantages_are_gae_on_the_atom_mean(collected) -> None:
    model, last_atoms, dones = collected
    buffer = model.rollout_buffer
    mean = buffer.atoms.mean(axis=-1)
    assert np.ptp(buffer.atoms, axis=-1).min() > 0  # the atoms differ: the mean is not any one of them
    np.testing.assert_allclose(buffer.values, mean, rtol=1e-5, atol=1e-6)
    rewards = buffer.rewards + buffer.gamma * buffer.bootstrap_atoms.mean(axis=-1)  # time-outs bootstrapped
    expected = gae(
        rewards, mean, buffer.episode_starts, last_atoms.mean(axis=-1), dones, buffer.gamma, buffer.gae_lambda
    )
    np.testing.assert_allclose(buffer.advantages, expected, rtol=1e-4, atol=1e-5)
    np.testing.assert_allclose(buffer.returns, expected + mean, rtol=1e-4, atol=1e-5)


def test_the_printed_expectation_loss_is_zero_at_beta_zero(collected) -> None:
    """Eq. 5 as printed compares the atoms' mean with their own distorted mean: at uniform weights the two
    are the same number, so huri-neutral's critic learns from the energy distance alone."""
    model, _, _ = collected
    buffer = model.rollout_buffer
    atoms = th.tensor(np.sort(buffer.atoms.reshape(-1, N_QUANTILES), axis=-1), requires_grad=True)
    weights = th.as_tensor(buffer.distortion_weights.reshape(-1, N_QUANTILES))
    targets = th.as_tensor(buffer.target_atoms.reshape(len(atoms), -1))
    loss = expectation_loss(atoms, targets, weights, "distorted")
    assert loss.item() < 1e-12
    loss.backward()
    assert atoms.grad.abs().max().item() < 1e-6
    assert expectation_loss(atoms, targets, weights, "target").item() > 1e-6  # the other reading is not
