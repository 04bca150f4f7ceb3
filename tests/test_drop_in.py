"""HuRiPPO as a drop-in for SB3's PPO: what the two share means the same, and a standard task runs as is."""

import warnings

import gymnasium as gym
import numpy as np
import pytest
import torch as th
from stable_baselines3 import PPO
from stable_baselines3.common.save_util import load_from_zip_file, save_to_zip_file
from torch import nn

from sb3_huri import HuRiPPO, UnnormalizedRewardWarning

PPO_KWARGS = dict(
    learning_rate=1e-3,
    n_steps=256,
    batch_size=32,
    n_epochs=3,
    gamma=0.98,
    gae_lambda=0.9,
    clip_range=0.1,
    normalize_advantage=False,
    ent_coef=0.01,
    vf_coef=0.7,
    max_grad_norm=0.3,
    use_sde=True,
    sde_sample_freq=4,
    target_kl=0.02,
    stats_window_size=50,
    policy_kwargs=dict(
        net_arch=dict(pi=[32], vf=[48, 16]),
        activation_fn=nn.ReLU,
        log_std_init=-1.0,
        ortho_init=False,
        optimizer_kwargs=dict(eps=1e-7),
    ),
)
"""PPO's keyword arguments, every one HuRiPPO shares set away from both defaults."""


def _layers(module: nn.Module) -> list[tuple[str, tuple[int, ...]]]:
    """The module's layers in order: each linear layer's weight shape, each activation's class."""
    return [
        ("linear", tuple(layer.weight.shape)) if isinstance(layer, nn.Linear) else (type(layer).__name__, ())
        for layer in module.modules()
        if not isinstance(layer, nn.Sequential)
    ]


def _what_it_ends_up_with(model) -> dict:
    """What an argument shared with PPO sets, read from the built model rather than from its arguments."""
    policy = model.policy
    extractor = policy.mlp_extractor
    optimizer = policy.optimizer
    return dict(
        learning_rate=model.lr_schedule(1.0),
        optimizer=(type(optimizer).__name__, optimizer.param_groups[0]["lr"], optimizer.defaults["eps"]),
        n_steps=model.n_steps,
        rollout=(model.rollout_buffer.buffer_size, model.rollout_buffer.n_envs),
        batch_size=model.batch_size,
        n_epochs=model.n_epochs,
        gamma=(model.gamma, model.rollout_buffer.gamma),
        gae_lambda=(model.gae_lambda, model.rollout_buffer.gae_lambda),
        clip_range=model.clip_range(1.0),
        normalize_advantage=model.normalize_advantage,
        coefficients=(model.ent_coef, model.vf_coef, model.max_grad_norm),
        sde=(model.use_sde, model.sde_sample_freq, policy.use_sde),
        target_kl=model.target_kl,
        stats_window=model._stats_window_size,
        actor=_layers(extractor.policy_net),
        critic=_layers(extractor.value_net),
        action_net=tuple(policy.action_net.weight.shape),
        value_inputs=policy.value_net.in_features,
        log_std=policy.log_std.detach().numpy().round(6).tolist(),
        ortho_init=policy.ortho_init,
    )


@pytest.mark.parametrize("kwargs", [{}, PPO_KWARGS], ids=["defaults", "every-shared-argument"])
@pytest.mark.parametrize("method", ["huri-baseline", "huri"])
def test_shared_arguments_mean_what_they_mean_in_ppo(kwargs, method):
    """One dict of PPO's keyword arguments (or none) builds SB3's PPO and HuRiPPO alike: same rollout and
    minibatch sizes, epochs, rates, coefficients, exploration, and the same actor and critic networks (the
    critic's head aside, whose width is the number of atoms)."""
    env = gym.make("Pendulum-v1")
    ppo = PPO("MlpPolicy", env, device="cpu", **kwargs)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UnnormalizedRewardWarning)
        huri = HuRiPPO("MlpPolicy", env, method=method, device="cpu", **kwargs)
    assert _what_it_ends_up_with(huri) == _what_it_ends_up_with(ppo)
    assert huri.policy.value_net.out_features == (1 if method == "huri-baseline" else 64)


def test_minibatches_by_count_are_an_alternative_to_their_size():
    """``n_minibatches`` splits the rollout evenly (the paper's presets use it); ``batch_size``, PPO's knob,
    wins when both are given (an RL Zoo override of a preset that splits its rollouts)."""
    env = gym.make("Pendulum-v1")
    assert HuRiPPO("MlpPolicy", env, method="huri-baseline", n_steps=256, n_minibatches=4).batch_size == 64
    assert HuRiPPO("MlpPolicy", env, method="huri-baseline", n_steps=256).batch_size == 64
    both = HuRiPPO("MlpPolicy", env, method="huri-baseline", n_steps=256, batch_size=32, n_minibatches=4)
    assert both.batch_size == 32
    with pytest.warns(UserWarning, match="does not divide the rollout"):
        HuRiPPO("MlpPolicy", env, method="huri-baseline", n_steps=100, batch_size=64)


def test_walker_learns_saves_and_loads_with_its_defaults(tmp_path):
    """``HuRiPPO("MlpPolicy", "Walker2d-v5")`` as a PPO user writes it: a Box observation, one env, every
    default. It tells that the absolute IQR band wants normalized rewards, learns a rollout, and saves and
    loads to the same policy."""
    with pytest.warns(UnnormalizedRewardWarning):
        model = HuRiPPO("MlpPolicy", "Walker2d-v5", seed=0, device="cpu").learn(2048)
    assert isinstance(model.observation_space, gym.spaces.Box)
    assert model.num_timesteps == 2048 and model._n_updates == 10
    observations = np.random.default_rng(0).normal(size=(5, *model.observation_space.shape))
    model.save(tmp_path / "walker")
    loaded = HuRiPPO.load(tmp_path / "walker", device="cpu")
    assert (loaded.n_steps, loaded.batch_size, loaded.n_epochs) == (2048, 64, 10)
    np.testing.assert_array_equal(
        loaded.predict(observations, deterministic=True)[0],
        model.predict(observations, deterministic=True)[0],
    )


def test_a_model_saved_with_the_earlier_default_networks_loads_with_them(tmp_path):
    """A model saved before HuRiPPO took PPO's defaults (no ``network_defaults`` in its save) that names no
    networks in its ``policy_kwargs`` was built with the paper's (``[512, 256, 128]``, ELU): it loads with
    them, weights and all. A model saved since loads with PPO's."""
    env = gym.make("Pendulum-v1")
    paper = dict(net_arch=dict(pi=[512, 256, 128], vf=[512, 256, 128]), activation_fn=nn.ELU)
    model = HuRiPPO("MlpPolicy", env, method="huri-baseline", n_steps=64, policy_kwargs=paper, device="cpu")
    model.save(tmp_path / "new")
    data, params, variables = load_from_zip_file(tmp_path / "new.zip")
    data["policy_kwargs"] = {k: v for k, v in data["policy_kwargs"].items() if k not in paper}
    del data["network_defaults"]
    save_to_zip_file(tmp_path / "earlier.zip", data=data, params=params, pytorch_variables=variables)

    loaded = HuRiPPO.load(tmp_path / "earlier.zip", device="cpu")
    assert _layers(loaded.policy.mlp_extractor.policy_net) == _layers(model.policy.mlp_extractor.policy_net)
    for saved, restored in zip(model.policy.parameters(), loaded.policy.parameters(), strict=True):
        assert th.equal(saved, restored)
    plain = HuRiPPO("MlpPolicy", env, method="huri-baseline", n_steps=64, device="cpu")
    plain.save(tmp_path / "plain")
    assert _layers(HuRiPPO.load(tmp_path / "plain.zip").policy.mlp_extractor.value_net) == [
        ("linear", (64, 3)),
        ("Tanh", ()),
        ("linear", (64, 64)),
        ("Tanh", ()),
    ]
