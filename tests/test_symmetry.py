"""Left-right symmetry: Zerith-1's mirror maps against its simulation, and HuRiPPO's symmetry loss."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
import torch as th
from stable_baselines3.common.vec_env import VecNormalize

import zerith_gym
from sb3_huri import HuRiPPO
from sb3_huri.common.mirror import NormalizedMirror, mirror_loss
from zerith_gym.core.observations import layout_slices
from zerith_gym.zerith1.observations import POLICY_LAYOUT, POLICY_SIZE
from zerith_gym.zerith1.symmetry import ACTION_MIRROR, POLICY_MIRROR, SignedPermutation

CLOCK = layout_slices(POLICY_LAYOUT)["clock_sin_cos"]


def test_the_maps_are_their_own_inverse_and_swap_the_legs():
    x = np.random.default_rng(0).normal(size=(5, POLICY_SIZE))
    np.testing.assert_array_equal(POLICY_MIRROR(POLICY_MIRROR(x)), x)
    np.testing.assert_array_equal(ACTION_MIRROR(ACTION_MIRROR(x[:, :12])), x[:, :12])
    action = np.arange(1.0, 13.0)  # left hip_yaw ... ankle_roll, then the right leg's
    np.testing.assert_array_equal(ACTION_MIRROR(action), [-7, -8, 9, 10, 11, -12, -1, -2, 3, 4, 5, -6])
    with pytest.raises(ValueError, match="permutation"):
        SignedPermutation(np.array([0, 0]), np.ones(2))


def test_a_mirrored_robot_sees_the_mirror_of_what_the_robot_sees():
    """Two nominal robots, one with the mirrored command and actions: each step, the second's observation is
    the mirror of the first's (the clock aside: a mirrored gait runs half a period later)."""
    env = zerith_gym.make_vec_env(2, seed=0, scenario="nominal", workers=0, obs_mode="policy")
    env.set_options([{"command": (0.5, 0.2, 0.3)}, {"command": (0.5, -0.2, -0.3)}])
    obs = env.reset()
    rng = np.random.default_rng(0)
    others = np.ones(POLICY_SIZE, dtype=bool)
    others[CLOCK] = False
    moved = 0.0
    for _ in range(60):
        action = rng.uniform(-0.3, 0.3, 12)
        obs, _, dones, _ = env.step(np.stack([action, ACTION_MIRROR(action)]))
        assert not dones.any()
        np.testing.assert_allclose(POLICY_MIRROR(obs[0])[others], obs[1][others], atol=1e-5)
        moved = max(moved, np.abs(obs[0] - obs[1])[others].max())
    assert moved > 0.5  # the two robots do differ: the test compares mirrored, not equal, states
    phase = np.linspace(0.0, 1.0, 7)
    clock = np.stack([np.sin(2 * np.pi * phase), np.cos(2 * np.pi * phase)], axis=-1)
    later = np.stack([np.sin(2 * np.pi * (phase + 0.5)), np.cos(2 * np.pi * (phase + 0.5))], axis=-1)
    np.testing.assert_allclose(POLICY_MIRROR.sign[CLOCK] * clock, later, atol=1e-12)
    env.close()


def test_the_mirror_in_normalized_units_is_the_normalized_mirror():
    rng = np.random.default_rng(1)
    mirror = SignedPermutation(np.array([2, 1, 0, 3]), np.array([1.0, -1.0, 1.0, -1.0]))
    mean, std = rng.normal(size=4), rng.uniform(0.5, 2.0, size=4)
    raw = rng.normal(size=(6, 4))
    normalized = th.as_tensor((raw - mean) / std, dtype=th.float32)
    carried = NormalizedMirror.build(mirror, mean, std)(normalized).numpy()
    np.testing.assert_allclose(carried, (mirror(raw) - mean) / std, rtol=1e-5, atol=1e-5)


def test_the_loss_is_zero_for_a_symmetric_actor_and_positive_otherwise():
    mirror = SignedPermutation(np.array([1, 0]), np.array([1.0, 1.0]))  # swap two entries
    observation_map, action_map = NormalizedMirror.build(mirror), NormalizedMirror.build(mirror)
    obs = th.randn(8, 2)
    symmetric = th.tensor([[2.0, 1.0], [1.0, 2.0]])  # commutes with the swap
    assert mirror_loss(lambda o: o @ symmetric, obs, observation_map, action_map).item() < 1e-10
    lopsided = th.tensor([[2.0, 0.0], [1.0, 1.0]])
    expected = ((obs.flip(-1) @ lopsided - (obs @ lopsided).flip(-1)) ** 2).sum(-1).mean()
    assert mirror_loss(lambda o: o @ lopsided, obs, observation_map, action_map).item() == pytest.approx(
        expected.item(), rel=1e-6
    )


def _asymmetry(mirror_coef: float) -> float:
    env = VecNormalize(zerith_gym.make_vec_env(8, seed=0, workers=0), norm_obs_keys=["policy"])
    model = HuRiPPO(
        "MultiInputPolicy", env, n_steps=16, n_epochs=4, mirror_coef=mirror_coef, seed=0,
        policy_kwargs=dict(net_arch=[32], log_std_init=-1.0),
    )  # fmt: skip
    model.learn(8 * 16 * 6)
    obs = th.as_tensor(model.rollout_buffer.observations["policy"].reshape(-1, POLICY_SIZE))
    with th.no_grad():
        value = mirror_loss(model.policy.actor_mean, obs, *model.mirror_maps()).item()
    env.close()
    return value


@pytest.mark.filterwarnings("ignore::sb3_huri.UnnormalizedRewardWarning")
def test_the_symmetry_loss_makes_the_actor_more_symmetric_and_is_saved(tmp_path):
    without, with_loss = _asymmetry(0.0), _asymmetry(10.0)
    assert with_loss < 0.5 * without
    env = zerith_gym.make_vec_env(2, seed=0, workers=0)
    model = HuRiPPO("MultiInputPolicy", env, n_steps=8, mirror_coef=0.5, policy_kwargs=dict(net_arch=[8]))
    model.learn(16)
    assert "train/mirror_loss" in model.logger.name_to_value
    model.save(tmp_path / "model.zip")
    assert HuRiPPO.load(tmp_path / "model.zip").mirror_coef == 0.5
    env.close()


@pytest.mark.filterwarnings("ignore::sb3_huri.UnnormalizedRewardWarning")
def test_a_symmetry_loss_needs_an_env_with_mirror_maps():
    with pytest.raises(ValueError, match="mirror_coef must be >= 0"):
        HuRiPPO("MlpPolicy", "Pendulum-v1", mirror_coef=-1.0)
    model = HuRiPPO("MlpPolicy", gym.make("Pendulum-v1"), n_steps=8, mirror_coef=1.0)
    with pytest.raises(ValueError, match="needs an env with `policy_mirror` and `action_mirror`"):
        model.learn(16)
