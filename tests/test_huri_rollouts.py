"""HuRi's advantages against SB3 PPO's: the buffer on shared data, and the huri-baseline method end to end."""

import numpy as np
import pytest
import torch as th
from gymnasium import spaces
from stable_baselines3 import PPO
from stable_baselines3.common.buffers import RolloutBuffer
from stable_baselines3.common.callbacks import BaseCallback
from stable_baselines3.common.env_util import make_vec_env
from stable_baselines3.common.vec_env import VecNormalize

from sb3_huri import HuRiPolicy, HuRiPPO
from sb3_huri.common import wang_weights
from sb3_huri.huri.buffers import HuRiRolloutBuffer

N_STEPS, N_ENVS, N_ATOMS, GAMMA, GAE_LAMBDA = 16, 3, 8, 0.97, 0.9


def test_collapsed_quantiles_with_beta_zero_give_sb3_advantages():
    rng = np.random.default_rng(0)
    obs_space, action_space = spaces.Box(-1, 1, (2,)), spaces.Box(-1, 1, (1,))
    sb3 = RolloutBuffer(N_STEPS, obs_space, action_space, gamma=GAMMA, gae_lambda=GAE_LAMBDA, n_envs=N_ENVS)
    huri = HuRiRolloutBuffer(
        N_STEPS,
        obs_space,
        action_space,
        gamma=GAMMA,
        gae_lambda=GAE_LAMBDA,
        n_envs=N_ENVS,
        n_quantiles=N_ATOMS,
    )
    values = rng.normal(size=(N_STEPS, N_ENVS)).astype(np.float32)
    dones = rng.random((N_STEPS, N_ENVS)) < 0.2
    time_outs = dones & (rng.random((N_STEPS, N_ENVS)) < 0.5)
    final_values = rng.normal(size=(N_STEPS, N_ENVS)).astype(np.float32)
    episode_starts = np.ones(N_ENVS, dtype=bool)
    for step in range(N_STEPS):
        obs, action = rng.normal(size=(N_ENVS, 2)), rng.normal(size=(N_ENVS, 1))
        reward, log_prob = rng.normal(size=N_ENVS).astype(np.float32), th.as_tensor(rng.normal(size=N_ENVS))
        value = th.as_tensor(values[step])
        # SB3's PPO adds gamma * V(final state) to the reward of a time-out step.
        sb3_reward = reward + GAMMA * np.where(time_outs[step], final_values[step], 0.0).astype(np.float32)
        sb3.add(obs, action, sb3_reward, episode_starts, value[:, None], log_prob)
        huri.add(obs, action, reward, episode_starts, value[:, None].expand(-1, N_ATOMS), log_prob)
        episode_starts = dones[step]
    last_values = th.as_tensor(rng.normal(size=N_ENVS).astype(np.float32))
    last_dones = dones[-1]

    steps, envs = np.nonzero(time_outs)
    collapsed = np.repeat(final_values[steps, envs][:, None], N_ATOMS, axis=1)
    huri.set_time_out_bootstrap(steps, envs, collapsed, final_values[steps, envs])
    weights = wang_weights(th.zeros(N_STEPS, N_ENVS), N_ATOMS).numpy()
    zeros = np.zeros((N_STEPS, N_ENVS))
    huri.set_risk(weights, zeros, zeros, zeros)
    sb3.compute_returns_and_advantage(last_values, last_dones)
    huri.compute_returns_and_advantage(
        last_values, last_dones, last_atoms=last_values[:, None].expand(-1, N_ATOMS).numpy()
    )

    np.testing.assert_allclose(huri.advantages, sb3.advantages, rtol=1e-5, atol=1e-5)
    np.testing.assert_allclose(huri.returns, sb3.returns, rtol=1e-5, atol=1e-5)
    # With lambda = 1 and a collapsed critic the target atoms are all the (Monte-Carlo) return.
    assert huri.target_atoms.shape == (N_STEPS, N_ENVS, N_ATOMS)
    np.testing.assert_allclose(huri.target_atoms.std(axis=-1), 0.0, atol=1e-5)


@pytest.mark.parametrize(
    ("env_id", "max_episode_steps", "options"),
    [
        ("Pendulum-v1", 20, {}),
        ("CartPole-v1", None, {}),
        # gSDE, and an approximate-KL early stop within the first epoch.
        ("Pendulum-v1", 20, dict(use_sde=True, sde_sample_freq=4, target_kl=1e-4, n_epochs=4)),
    ],
)
def test_huri_baseline_trains_exactly_like_sb3_ppo(env_id, max_episode_steps, options):
    """Same seed, same policy class: identical rollouts, advantages, returns and updated parameters."""
    env_kwargs = {"max_episode_steps": max_episode_steps} if max_episode_steps else None
    settings = dict(n_steps=32, batch_size=16, n_epochs=2, gamma=GAMMA, gae_lambda=GAE_LAMBDA, seed=3)
    settings |= options
    settings |= dict(ent_coef=0.01, vf_coef=1.0, max_grad_norm=1.0, learning_rate=1e-3)
    policy_kwargs = dict(net_arch=[32, 32])
    # Each model seeds the global random generators when built: build and train one after the other.
    ppo = PPO(
        HuRiPolicy,
        make_vec_env(env_id, n_envs=2, seed=3, env_kwargs=env_kwargs),
        policy_kwargs=dict(policy_kwargs, n_quantiles=1),
        **settings,
    ).learn(64)
    huri = HuRiPPO(
        "MlpPolicy",
        make_vec_env(env_id, n_envs=2, seed=3, env_kwargs=env_kwargs),
        method="huri-baseline",
        policy_kwargs=policy_kwargs,
        **settings,
    ).learn(64)
    ppo_buffer, huri_buffer = ppo.rollout_buffer, huri.rollout_buffer
    # Pendulum's short time limit and CartPole's falls: the rollout holds time-outs or terminals.
    assert huri_buffer.episode_starts[1:].any()
    # SB3 adds gamma * V(final state) to a time-out's reward in place; HuRi keeps it apart.
    bootstrapped_rewards = huri_buffer.rewards + GAMMA * huri_buffer.bootstrap_values
    np.testing.assert_allclose(bootstrapped_rewards, ppo_buffer.rewards, rtol=1e-5, atol=1e-5)
    for name in ("observations", "actions", "log_probs", "values", "advantages", "returns"):
        np.testing.assert_allclose(
            getattr(huri_buffer, name), getattr(ppo_buffer, name), rtol=1e-5, atol=1e-5
        )
    for (name, ppo_param), huri_param in zip(
        ppo.policy.state_dict().items(), huri.policy.state_dict().values(), strict=True
    ):
        th.testing.assert_close(huri_param, ppo_param, rtol=1e-5, atol=1e-6, msg=name)
    assert huri._n_updates == ppo._n_updates
    if "target_kl" in options:
        assert huri._n_updates < 2 * options["n_epochs"]


def test_time_out_targets_bootstrap_from_the_final_observation():
    """A time-out step's target atoms are ``r + gamma * Z(final observation)``, sorted atoms of that state."""
    n_envs, n_steps = 2, 24
    env = make_vec_env("Pendulum-v1", n_envs=n_envs, seed=0, env_kwargs=dict(max_episode_steps=7))
    model = HuRiPPO("MlpPolicy", env, n_steps=n_steps, method="huri-no-rnd", gamma=0.9, n_quantiles=8, seed=0)
    model.learn(n_steps * n_envs)
    buffer = model.rollout_buffer
    steps, envs = np.nonzero(buffer.bootstrap_values)
    assert buffer.has_time_outs and len(steps) == (n_steps // 7) * n_envs
    assert (np.diff(buffer.bootstrap_atoms[steps, envs], axis=-1) >= 0).all()
    assert (np.diff(buffer.target_atoms, axis=-1) >= 0).all()  # sorted once, for every epoch's loss
    # get() flattened the targets env-major (row e * n_steps + t): restore the (step, env) layout.
    targets = buffer.target_atoms.reshape(n_envs, n_steps, -1).swapaxes(0, 1)
    expected = buffer.rewards[steps, envs][:, None] + 0.9 * buffer.bootstrap_atoms[steps, envs]
    np.testing.assert_allclose(targets[steps, envs], expected, rtol=1e-5, atol=1e-5)
    # The final observation's atoms are the critic's prediction for it, not the next episode's first state.
    first_of_next = buffer.atoms[steps + 1, envs] if (steps + 1 < n_steps).all() else None
    if first_of_next is not None:
        assert not np.allclose(first_of_next, buffer.bootstrap_atoms[steps, envs])


class FinalObservationRecorder(BaseCallback):
    """Keeps the final observations of truncated episodes as the algorithm saw them, and at the end of the
    rollout (before the update) the critic's sorted atoms for them."""

    def __init__(self):
        super().__init__()
        self.final_observations: dict[tuple[int, int], np.ndarray] = {}
        self.expected_atoms: dict[tuple[int, int], np.ndarray] = {}

    def _on_step(self) -> bool:
        step = self.locals["rollout_buffer"].pos
        for env_index, info in enumerate(self.locals["infos"]):
            if info.get("TimeLimit.truncated", False):
                self.final_observations[(step, env_index)] = info["terminal_observation"]
        return True

    def _on_rollout_end(self) -> None:
        for key, observation in self.final_observations.items():
            with th.no_grad():
                atoms = self.model.policy.predict_values(self.model.policy.obs_to_tensor(observation)[0])
            self.expected_atoms[key] = th.sort(atoms, dim=-1).values[0].numpy()


def test_time_outs_bootstrap_from_the_normalized_final_observation_under_vecnormalize():
    """As SB3's PPO: the final observation is the one VecNormalize normalized, not the raw one."""
    n_envs, n_steps = 2, 20
    env = VecNormalize(
        make_vec_env("Pendulum-v1", n_envs=n_envs, seed=0, env_kwargs=dict(max_episode_steps=6)),
        norm_obs=True,
        norm_reward=True,
    )
    model = HuRiPPO(
        "MlpPolicy", env, n_steps=n_steps, n_epochs=1, method="huri-no-rnd", n_quantiles=8, seed=0
    )
    recorder = FinalObservationRecorder()
    model.learn(n_steps * n_envs, callback=recorder)
    buffer = model.rollout_buffer
    assert len(recorder.expected_atoms) == (n_steps // 6) * n_envs
    for (step, env_index), expected in recorder.expected_atoms.items():
        np.testing.assert_allclose(buffer.bootstrap_atoms[step, env_index], expected, rtol=1e-5, atol=1e-6)
        raw = env.unnormalize_obs(recorder.final_observations[(step, env_index)])
        assert not np.allclose(raw, recorder.final_observations[(step, env_index)])
