"""HuRiPPO's options beyond the paper's defaults: policy_kwargs and load round trips, the reward-normalization
warning, the KL-adaptive learning rate, the expectation-loss reading and the RND settings."""

import warnings

import gymnasium as gym
import numpy as np
import pytest
import torch as th
from huri_helpers import SMALL, KeyRecorder, dict_env, state_dicts_equal
from stable_baselines3.common.env_util import make_vec_env
from stable_baselines3.common.logger import Logger
from stable_baselines3.common.vec_env import VecNormalize

from sb3_huri import HuRiPPO, UnnormalizedRewardWarning

pytestmark = pytest.mark.filterwarnings("ignore::sb3_huri.UnnormalizedRewardWarning")


def architecture(model: HuRiPPO) -> dict[str, tuple[int, ...]]:
    return {
        key: tuple(value.shape) for key, value in model.policy.state_dict().items() if hasattr(value, "shape")
    }


# --- policy_kwargs and load round trips -------------------------------------------------------------


def test_policy_kwargs_of_a_model_rebuild_the_same_networks():
    env = dict_env()
    model = HuRiPPO(
        "MlpPolicy", env, n_quantiles=16, rnd_kwargs=dict(output_dim=8, predictor_net_arch=[24]), **SMALL
    )
    assert model.policy_kwargs["n_quantiles"] == 16 and model.policy_kwargs["rnd_kwargs"]["output_dim"] == 8
    again = HuRiPPO("MlpPolicy", env, n_steps=32, policy_kwargs=model.policy_kwargs)
    assert again.n_quantiles == 16 and again.rnd_kwargs == model.rnd_kwargs
    assert architecture(again) == architecture(model)
    # The same values passed both ways agree; the carried RND settings do not switch RND on for a method
    # without it, and a scalar-critic method refuses a quantile critic.
    HuRiPPO("MlpPolicy", env, n_quantiles=16, policy_kwargs=model.policy_kwargs, **{"n_steps": 32})
    no_rnd = HuRiPPO("MlpPolicy", env, method="huri-no-rnd", n_steps=32, policy_kwargs=model.policy_kwargs)
    assert no_rnd.policy.rnd is None and no_rnd.policy_kwargs["rnd_kwargs"] is None
    with pytest.raises(ValueError, match="n_quantiles"):
        HuRiPPO("MlpPolicy", env, method="huri-baseline", n_steps=32, policy_kwargs=model.policy_kwargs)


@pytest.mark.parametrize("which", ["saved", "network options only"])
def test_load_with_custom_policy_kwargs(tmp_path, which):
    env = dict_env()
    model = HuRiPPO("MlpPolicy", env, n_quantiles=16, rnd_kwargs=dict(output_dim=8), seed=0, **SMALL).learn(
        64
    )
    model.save(tmp_path / "model.zip")
    custom = dict(model.policy_kwargs) if which == "saved" else dict(net_arch=[32, 32])
    loaded = HuRiPPO.load(tmp_path / "model.zip", env=env, custom_objects={"policy_kwargs": custom})
    state_dicts_equal(model.policy.state_dict(), loaded.policy.state_dict())
    obs = env.reset()
    np.testing.assert_array_equal(
        loaded.predict(obs, deterministic=True)[0], model.predict(obs, deterministic=True)[0]
    )
    np.testing.assert_array_equal(loaded.assess_risk(obs).risk, model.assess_risk(obs).risk)
    loaded.learn(64, reset_num_timesteps=False)


# --- reward normalization ---------------------------------------------------------------------------


def test_learning_without_reward_normalization_warns_how_to_normalize():
    model = HuRiPPO("MlpPolicy", dict_env(), method="huri", **SMALL)  # the absolute band
    with pytest.warns(UnnormalizedRewardWarning, match=r"normalize.*VecNormalize\(env, norm_reward=True\)"):
        model.learn(64)
    model.set_env(VecNormalize(dict_env(), norm_reward=False))
    with pytest.warns(UnnormalizedRewardWarning, match="normalize"):
        model.learn(64)


@pytest.mark.parametrize(
    "setting", ["VecNormalize", "NormalizeReward", "huri-baseline", "huri-no-iqr", "huri-percentile"]
)
def test_no_warning_with_normalized_rewards_or_without_absolute_iqr_thresholds(setting):
    """Normalized rewards, no IQR band, or the scale-free band: nothing to warn of."""
    method = setting if setting.startswith("huri") else "huri"
    if setting == "VecNormalize":
        env = VecNormalize(dict_env(), norm_obs=False, norm_reward=True)
    elif setting == "NormalizeReward":
        env = make_vec_env("Pendulum-v1", n_envs=2, seed=0, wrapper_class=gym.wrappers.NormalizeReward)
    else:
        env = dict_env()
    model = HuRiPPO("MlpPolicy", env, method=method, **SMALL)
    with warnings.catch_warnings():
        warnings.simplefilter("error", UnnormalizedRewardWarning)
        model.learn(64)


# --- KL-adaptive learning rate ----------------------------------------------------------------------


def kl_adaptive_model(desired_kl: float, **kwargs) -> tuple[HuRiPPO, list[float], KeyRecorder]:
    """A model whose per-minibatch KL values are recorded as the learning rate adapts to them."""
    model = HuRiPPO("MlpPolicy", dict_env(), learning_rate=1e-3, desired_kl=desired_kl, seed=0, **SMALL)
    recorder = KeyRecorder()
    model.set_logger(Logger(folder=None, output_formats=[recorder]))
    kls: list[float] = []
    adapt = model._adapt_learning_rate

    def recording(approx_kl: float) -> None:
        kls.append(approx_kl)
        adapt(approx_kl)

    model._adapt_learning_rate = recording  # type: ignore[method-assign]
    return model, kls, recorder


def replay(learning_rate: float, desired_kl: float, kls: list[float]) -> float:
    """The legged-robot PPO rule written out: / 1.5 above 2 x desired, x 1.5 below half, in [1e-6, 1e-2]."""
    for kl in kls:
        if kl > 2 * desired_kl:
            learning_rate = max(learning_rate / 1.5, 1e-6)
        elif 0 < kl < desired_kl / 2:
            learning_rate = min(learning_rate * 1.5, 1e-2)
    return learning_rate


@pytest.mark.parametrize(("desired_kl", "direction"), [(1e-7, "down"), (10.0, "up"), (2e-3, "either")])
def test_kl_adaptive_learning_rate_follows_the_rule_per_minibatch(desired_kl, direction):
    model, kls, recorder = kl_adaptive_model(desired_kl)
    model.learn(128)  # two updates of 2 epochs x 4 minibatches
    assert len(kls) == 16
    expected = replay(1e-3, desired_kl, kls)
    assert model.kl_learning_rate == pytest.approx(expected, rel=1e-12)
    assert all(group["lr"] == pytest.approx(expected) for group in model.policy.optimizer.param_groups)
    if direction == "down":
        assert expected <= 1e-3 / 1.5**5
    elif direction == "up":
        assert expected == pytest.approx(1e-2)  # the upper bound
    # Logged: the mean rate of the update's minibatch steps (the schedule's is not used).
    first_update = [replay(1e-3, desired_kl, kls[: k + 1]) for k in range(8)]
    assert recorder.records["train/learning_rate"][0] == pytest.approx(np.mean(first_update))


def test_kl_adaptive_learning_rate_is_saved_and_continues(tmp_path):
    model = HuRiPPO("MlpPolicy", dict_env(), learning_rate=1e-3, desired_kl=1e-7, seed=0, **SMALL).learn(64)
    model.save(tmp_path / "model.zip")
    loaded = HuRiPPO.load(tmp_path / "model.zip", env=dict_env())
    assert loaded.desired_kl == 1e-7 and loaded.kl_learning_rate == model.kl_learning_rate < 1e-3
    loaded.learn(64, reset_num_timesteps=False)
    assert loaded.kl_learning_rate < model.kl_learning_rate


def _actor_and_critic(model: HuRiPPO) -> tuple[list[th.Tensor], list[th.Tensor]]:
    critic_ids = {id(p) for p in model.policy.critic_parameters()}
    rnd_ids = {id(p) for p in model.policy.rnd.parameters()} if model.policy.rnd is not None else set()
    params = [p for p in model.policy.parameters() if id(p) not in rnd_ids]
    actor = [p.detach().clone() for p in params if id(p) not in critic_ids]
    return actor, [p.detach().clone() for p in model.policy.critic_parameters()]


def test_critic_learning_rate_trains_the_critic_at_its_own_rate(tmp_path):
    """Actor at 1e-12 (it hardly moves), critic at 1e-3 (it learns); both rates survive save and load."""
    model = HuRiPPO("MlpPolicy", dict_env(), learning_rate=1e-12, critic_learning_rate=1e-3, seed=0, **SMALL)
    recorder = KeyRecorder()
    model.set_logger(Logger(folder=None, output_formats=[recorder]))
    actor_before, critic_before = _actor_and_critic(model)
    model.learn(128)
    actor_after, critic_after = _actor_and_critic(model)
    actor_moved = max((a - b).abs().max().item() for a, b in zip(actor_after, actor_before, strict=True))
    critic_moved = max((a - b).abs().max().item() for a, b in zip(critic_after, critic_before, strict=True))
    assert actor_moved < 1e-9 < 1e-4 < critic_moved
    names = {group["name"]: group["lr"] for group in model.policy.optimizer.param_groups}
    assert names == {"actor": 1e-12, "critic": 1e-3}
    assert recorder.records["train/critic_learning_rate"][-1] == pytest.approx(1e-3)
    model.save(tmp_path / "model.zip")
    loaded = HuRiPPO.load(tmp_path / "model.zip", env=dict_env())
    state_dicts_equal(loaded.policy.optimizer.state_dict(), model.policy.optimizer.state_dict())
    loaded.learn(64, reset_num_timesteps=False)
    assert {g["name"]: g["lr"] for g in loaded.policy.optimizer.param_groups} == names


def test_desired_kl_adapts_only_the_actor_rate_when_the_critic_has_its_own():
    model = HuRiPPO(
        "MlpPolicy",
        dict_env(),
        learning_rate=1e-3,
        critic_learning_rate=lambda progress: 5e-4 * progress,
        desired_kl=1e-7,
        seed=0,
        **SMALL,
    )
    model.learn(128)
    rates = {group["name"]: group["lr"] for group in model.policy.optimizer.param_groups}
    assert rates["actor"] == model.kl_learning_rate < 1e-3 / 1.5**5  # pushed down by the tiny KL target
    assert rates["critic"] == pytest.approx(5e-4 * model._current_progress_remaining)


def test_a_model_saved_with_one_rate_loads_with_a_critic_learning_rate(tmp_path):
    HuRiPPO("MlpPolicy", dict_env(), seed=0, **SMALL).learn(64).save(tmp_path / "model.zip")
    with pytest.warns(UserWarning, match="the saved Adam moments are dropped, the weights are kept"):
        loaded = HuRiPPO.load(tmp_path / "model.zip", env=dict_env(), critic_learning_rate=1e-3)
    loaded.learn(64, reset_num_timesteps=False)
    assert {g["name"]: g["lr"] for g in loaded.policy.optimizer.param_groups}["critic"] == 1e-3


@pytest.mark.parametrize("value", [0.0, -1e-3, "fast"])
def test_bad_critic_learning_rate_is_refused(value):
    with pytest.raises(ValueError, match="critic_learning_rate must be None, a float > 0 or a schedule"):
        HuRiPPO("MlpPolicy", dict_env(), critic_learning_rate=value, **SMALL)


def test_target_kl_early_stop_still_works_with_a_desired_kl():
    model, kls, _ = kl_adaptive_model(1e-3)
    model.target_kl = 1e-9
    model.learn(64)
    # The first minibatch barely moves the policy (KL ~ 0); the second exceeds 1.5 x target_kl and stops.
    assert len(kls) <= 1
    assert model._n_updates == 1  # stopped in the first of 2 epochs


# --- expectation loss and RND settings --------------------------------------------------------------


@pytest.mark.parametrize("reading", ["target", "distorted"])
def test_expectation_loss_reading_is_used_in_training_and_saved(tmp_path, reading):
    model = HuRiPPO("MlpPolicy", dict_env(), expectation_loss=reading, seed=0, **SMALL)
    recorder = KeyRecorder()
    model.set_logger(Logger(folder=None, output_formats=[recorder]))
    model.learn(64)
    # Recompute the logged loss on the last minibatch's ingredients at the end: both readings give
    # different values on the same rollout.
    buffer = model.rollout_buffer
    with th.no_grad():
        batch = next(buffer.get(None))
        atoms = th.sort(model.policy.predict_values(batch.observations), dim=-1).values
        target = (atoms.mean(-1) - batch.target_atoms.mean(-1)).pow(2).mean().item()
        distorted = (atoms.mean(-1) - (batch.distortion_weights * atoms).sum(-1)).pow(2).mean().item()
    assert target != pytest.approx(distorted, rel=0.1)
    model.save(tmp_path / "model.zip")
    assert HuRiPPO.load(tmp_path / "model.zip").expectation_loss == reading


def test_default_expectation_loss_is_eq_5_as_printed():
    assert HuRiPPO("MlpPolicy", "Pendulum-v1", n_steps=64).expectation_loss == "distorted"


def test_rnd_kwargs_reach_the_rnd_module():
    model = HuRiPPO(
        "MlpPolicy",
        dict_env(),
        rnd_kwargs=dict(target_net_arch=[8], predictor_net_arch=[4], output_dim=3, learning_rate=0.5),
        **SMALL,
    )
    rnd = model.policy.rnd
    assert [layer.out_features for layer in rnd.target if isinstance(layer, th.nn.Linear)] == [8, 3]
    assert [layer.out_features for layer in rnd.predictor if isinstance(layer, th.nn.Linear)] == [4, 3]
    assert rnd.optimizer.param_groups[0]["lr"] == 0.5 and rnd.normalize_error
    assert HuRiPPO("MlpPolicy", dict_env(), method="huri-no-rnd", **SMALL).rnd_kwargs is None


def test_beta_rnd_is_material_on_the_first_rollouts_and_falls_as_states_become_familiar():
    model = HuRiPPO(
        "MlpPolicy", dict_env(), seed=0, n_steps=64, n_minibatches=4, n_epochs=5,
        policy_kwargs=dict(net_arch=[32]),
    )  # fmt: skip
    recorder = KeyRecorder()
    model.set_logger(Logger(folder=None, output_formats=[recorder]))
    model.learn(128 * 12)
    beta_rnd = np.array(recorder.records["rollout/beta_rnd_mean"])
    assert beta_rnd[0] > 0.5
    assert beta_rnd[-3:].mean() < 0.5 * beta_rnd[0]
