"""HuRiPPO end to end: learning, asymmetric observations, what SB3 users rely on, bad input."""

import gymnasium as gym
import numpy as np
import pytest
import torch as th
from gymnasium import spaces
from huri_helpers import SMALL, KeyRecorder, dict_env, state_dicts_equal
from stable_baselines3 import PPO
from stable_baselines3.common.callbacks import BaseCallback
from stable_baselines3.common.env_util import make_vec_env
from stable_baselines3.common.logger import Logger
from stable_baselines3.common.vec_env import DummyVecEnv, VecNormalize

from sb3_huri import METHODS, HuRiPolicy, HuRiPPO
from sb3_huri.huri.risk import WANG_LOG_KEYS

# Most tests learn on raw rewards on purpose (small, exact checks); the warning has its own test.
pytestmark = pytest.mark.filterwarnings("ignore::sb3_huri.UnnormalizedRewardWarning")


# --- learning --------------------------------------------------------------------------------------


@pytest.mark.parametrize("method", list(METHODS))
def test_every_method_learns_on_pendulum_with_several_envs(method):
    env = make_vec_env("Pendulum-v1", n_envs=2, seed=0, env_kwargs=dict(max_episode_steps=40))
    model = HuRiPPO("MlpPolicy", env, method=method, seed=0, **SMALL)
    before = model.policy.parameters_to_vector()
    model.learn(128)
    assert model.num_timesteps == 128
    assert not np.allclose(model.policy.parameters_to_vector(), before)
    assert (model.policy.rnd is not None) == METHODS[method].use_rnd
    assert model.policy.n_quantiles == (64 if METHODS[method].distributional else 1)
    assert model.rollout_buffer.has_time_outs


def test_discrete_actions_learn():
    model = HuRiPPO("MlpPolicy", make_vec_env("CartPole-v1", n_envs=2, seed=0), seed=0, **SMALL).learn(64)
    action, _ = model.predict(np.zeros(4, dtype=np.float32), deterministic=True)
    assert action in (0, 1)


def test_zerith1_learns_with_several_envs_and_time_outs():
    pytest.importorskip("zerith_gym")
    env = make_vec_env("Zerith1-v0", n_envs=2, seed=0, env_kwargs=dict(max_episode_steps=12))
    model = HuRiPPO("MlpPolicy", env, n_steps=24, n_epochs=1, seed=0)
    assert model.policy.mlp_extractor.actor_dim == 46
    assert model.policy.features_dim == 46 + spaces.flatdim(env.observation_space["critic"])
    model.learn(96)
    assert model.num_timesteps == 96 and model.rollout_buffer.has_time_outs
    assert np.isfinite(model.rollout_buffer.advantages).all()


def test_zerith1_flat_policy_observation_works_with_plain_mlp():
    pytest.importorskip("zerith_gym")
    env = make_vec_env("Zerith1-v0", n_envs=1, seed=0, env_kwargs=dict(obs_mode="policy"))
    model = HuRiPPO(
        "MlpPolicy", env, n_steps=16, n_epochs=1, seed=0, **{"policy_kwargs": dict(net_arch=[32])}
    )
    assert model.policy.features_dim == 46
    model.learn(16)


# --- asymmetric actor-critic ------------------------------------------------------------------------


@pytest.mark.parametrize("policy", ["MlpPolicy", "MultiInputPolicy", HuRiPolicy])
def test_dict_observation_gives_an_asymmetric_policy(policy):
    model = HuRiPPO(policy, dict_env(), seed=0, **SMALL)
    assert model.policy.mlp_extractor.actor_dim == 3
    assert model.policy.mlp_extractor.policy_net[0].in_features == 3
    assert model.policy.mlp_extractor.value_net[0].in_features == 5
    assert model.policy.rnd.predictor[0].in_features == 5
    model.learn(64)


def test_actor_ignores_the_critic_key_and_critic_reads_it():
    model = HuRiPPO("MlpPolicy", dict_env(), seed=0, **SMALL)
    policy_obs = np.random.default_rng(0).normal(size=(5, 3)).astype(np.float32)
    obs_a = {"policy": policy_obs, "critic": np.zeros((5, 2), np.float32)}
    obs_b = {"policy": policy_obs, "critic": np.full((5, 2), 3.0, np.float32)}
    actions_a, _ = model.predict(obs_a, deterministic=True)
    actions_b, _ = model.predict(obs_b, deterministic=True)
    np.testing.assert_array_equal(actions_a, actions_b)
    tensor_a, tensor_b = model.policy.obs_to_tensor(obs_a)[0], model.policy.obs_to_tensor(obs_b)[0]
    with th.no_grad():
        mean_a = model.policy.get_distribution(tensor_a).distribution.mean
        th.testing.assert_close(mean_a, model.policy.get_distribution(tensor_b).distribution.mean)
        assert not th.allclose(model.policy.predict_values(tensor_a), model.policy.predict_values(tensor_b))


def test_sb3_ppo_can_use_the_asymmetric_policy_with_a_scalar_critic():
    model = PPO(
        HuRiPolicy, dict_env(), n_steps=32, batch_size=32, policy_kwargs=dict(n_quantiles=1, net_arch=[32])
    )
    model.learn(64)
    assert model.policy.mlp_extractor.actor_dim == 3


@pytest.mark.parametrize("method", ["huri-no-rnd", "huri", "huri-cvar0.5", "huri-baseline"])
def test_assess_risk_reports_sorted_atoms_and_the_methods_risk(method):
    model = HuRiPPO("MlpPolicy", dict_env(n_envs=1), method=method, seed=0, **SMALL)
    model.learn(32)
    first_obs = {key: obs[0] for key, obs in model.rollout_buffer.observations.items()}
    assessment = model.assess_risk(first_obs)
    # One observation gives unbatched results, as SB3's predict does.
    assert assessment.atoms.shape == (model.n_quantiles,)
    assert all(np.ndim(field) == 0 for field in assessment[1:])
    assert (np.diff(assessment.atoms) >= 0).all()
    assert assessment.atoms.min() <= assessment.value <= assessment.atoms.max()
    if method == "huri-no-rnd":
        assert assessment.risk in (-1.0, 0.0, 1.0)
    elif method == "huri":
        iqr_level = assessment.risk - np.tanh(assessment.rnd_error)
        assert assessment.rnd_error > 0 and min(abs(iqr_level - level) for level in (-1, 0, 1)) < 1e-5
    elif method == "huri-cvar0.5":
        assert assessment.risk == 0.5
        assert assessment.value == pytest.approx(assessment.atoms[:32].mean(), rel=1e-5)


def test_assess_risk_of_a_batch_has_one_row_per_observation_and_matches_single_calls():
    model = HuRiPPO("MlpPolicy", dict_env(n_envs=1), seed=0, **SMALL).learn(32)
    batch = {key: obs[:5] for key, obs in model.rollout_buffer.observations.items()}
    assessment = model.assess_risk(batch)
    assert assessment.atoms.shape == (5, model.n_quantiles)
    assert all(field.shape == (5,) for field in assessment[1:])
    for row in range(5):
        single = model.assess_risk({key: obs[row] for key, obs in batch.items()})
        for batched_field, single_field in zip(assessment, single, strict=True):
            np.testing.assert_allclose(batched_field[row], single_field, rtol=1e-5, atol=1e-6)


# --- logging ----------------------------------------------------------------------------------------


def test_risk_and_loss_keys_are_logged():
    model = HuRiPPO("MlpPolicy", dict_env(), seed=0, **SMALL)
    recorder = KeyRecorder()
    model.set_logger(Logger(folder=None, output_formats=[recorder]))
    model.learn(128)
    expected = {
        *("rollout/beta_mean", "rollout/iqr_mean", "rollout/rnd_error", "rollout/beta_iqr_averse"),
        *("rollout/beta_iqr_mean", "rollout/beta_rnd_mean"),
        *("rollout/beta_iqr_neutral", "rollout/beta_iqr_seeking", "train/quantile_loss"),
        *("train/expectation_loss", "train/rnd_loss", "train/policy_gradient_loss", "train/value_loss"),
    }
    assert expected <= recorder.records.keys()
    shares = [recorder.records[f"rollout/beta_iqr_{kind}"][-1] for kind in ("averse", "neutral", "seeking")]
    assert sum(shares) == pytest.approx(1.0)
    # beta = beta_IQR + beta_RND, and the IQR part is the shares weighted by the risk levels (-1, 0, 1).
    records = {key: np.array(values) for key, values in recorder.records.items()}
    np.testing.assert_allclose(
        records["rollout/beta_mean"],
        records["rollout/beta_iqr_mean"] + records["rollout/beta_rnd_mean"],
        rtol=1e-5,
    )
    np.testing.assert_allclose(
        records["rollout/beta_iqr_mean"],
        records["rollout/beta_iqr_averse"] - records["rollout/beta_iqr_seeking"],
        atol=1e-6,
    )
    assert (records["rollout/beta_rnd_mean"] > 0).all() and (records["rollout/beta_rnd_mean"] <= 1).all()
    # The names true for Wang and CVaR alike hold the same values (the beta names are Wang's only).
    for neutral, beta in WANG_LOG_KEYS.items():
        np.testing.assert_array_equal(records[neutral], records[beta])


class InitCounter(BaseCallback):
    """Counts how often SB3 initializes it, and checks the RND predictor trained before its rollout end."""

    def __init__(self):
        super().__init__()
        self.inits, self.rollout_ends = 0, 0

    def _init_callback(self) -> None:
        self.inits += 1

    def _on_step(self) -> bool:
        return True

    def _on_rollout_end(self) -> None:
        self.rollout_ends += 1
        assert "train/rnd_loss" in self.logger.name_to_value


@pytest.mark.parametrize("as_list", [False, True])
def test_user_callbacks_are_initialized_once_next_to_the_rnd_trainer(as_list):
    model = HuRiPPO("MlpPolicy", dict_env(), seed=0, **SMALL)
    counter = InitCounter()
    model.learn(128, callback=[counter] if as_list else counter)
    assert (counter.inits, counter.rollout_ends) == (1, 2)
    # Plain functions are callbacks too (SB3 wraps them in a ConvertCallback).
    calls = []
    model.learn(64, callback=lambda locals_, globals_: calls.append(1) is None)
    assert len(calls) == 32


def test_progress_bar_and_tensorboard(tmp_path):
    for module in ("tensorboard", "tqdm", "rich"):
        pytest.importorskip(module)
    model = HuRiPPO("MlpPolicy", "Pendulum-v1", tensorboard_log=str(tmp_path), **SMALL)
    model.learn(64, progress_bar=True)
    assert list(tmp_path.glob("HuRiPPO_1/events.out.tfevents.*"))


# --- save, load, predict, seeding -------------------------------------------------------------------


def test_save_load_round_trip_keeps_everything_and_learning_continues(tmp_path):
    env = dict_env(max_episode_steps=20)
    model = HuRiPPO("MultiInputPolicy", env, method="huri", seed=0, **SMALL).learn(64)
    observations = env.reset()
    actions, _ = model.predict(observations, deterministic=True)
    model.save(tmp_path / "model.zip")

    loaded = HuRiPPO.load(tmp_path / "model.zip", env=env)
    state_dicts_equal(model.policy.state_dict(), loaded.policy.state_dict())
    assert loaded.policy.rnd.obs_rms.count == model.policy.rnd.obs_rms.count > 1
    np.testing.assert_array_equal(loaded.policy.rnd.obs_rms.var, model.policy.rnd.obs_rms.var)
    state_dicts_equal(model.policy.optimizer.state_dict(), loaded.policy.optimizer.state_dict())
    state_dicts_equal(model.policy.rnd.optimizer.state_dict(), loaded.policy.rnd.optimizer.state_dict())
    assert loaded.policy.rnd.optimizer.param_groups[0]["fused"]  # the saved settings do not unfuse its step
    np.testing.assert_array_equal(loaded.predict(observations, deterministic=True)[0], actions)
    assert (loaded.method, loaded.n_quantiles, loaded.use_rnd, loaded.batch_size) == ("huri", 64, True, 16)

    before = loaded.policy.parameters_to_vector()
    rnd_before = loaded.policy.rnd.predictor[0].weight.detach().clone()
    loaded.learn(64, reset_num_timesteps=False)
    assert loaded.num_timesteps == 128
    assert not np.allclose(loaded.policy.parameters_to_vector(), before)
    assert not th.allclose(loaded.policy.rnd.predictor[0].weight, rnd_before)


def test_policy_alone_save_load(tmp_path):
    model = HuRiPPO("MlpPolicy", dict_env(), seed=0, **SMALL).learn(64)
    model.policy.save(tmp_path / "policy.pth")
    policy = HuRiPolicy.load(tmp_path / "policy.pth")
    state_dicts_equal(model.policy.state_dict(), policy.state_dict())
    obs = {"policy": np.ones((4, 3), np.float32), "critic": np.ones((4, 2), np.float32)}
    np.testing.assert_array_equal(
        policy.predict(obs, deterministic=True)[0], model.predict(obs, deterministic=True)[0]
    )


def test_set_env_and_predict_shapes():
    model = HuRiPPO("MlpPolicy", "Pendulum-v1", **SMALL)
    model.set_env(make_vec_env("Pendulum-v1", n_envs=1, seed=1))
    single, state = model.predict(np.zeros(3, np.float32), deterministic=True)
    batch, _ = model.predict(np.zeros((4, 3), np.float32), deterministic=True)
    assert single.shape == (1,) and batch.shape == (4, 1) and state is None
    # Deterministic predictions repeat; stochastic ones vary.
    obs = np.random.default_rng(0).normal(size=(8, 3)).astype(np.float32)
    np.testing.assert_array_equal(
        model.predict(obs, deterministic=True)[0], model.predict(obs, deterministic=True)[0]
    )
    assert not np.array_equal(model.predict(obs)[0], model.predict(obs)[0])


def test_same_seed_same_result():
    def train() -> np.ndarray:
        model = HuRiPPO("MlpPolicy", dict_env(max_episode_steps=20), seed=7, sr_lambda=0.5, **SMALL).learn(
            128
        )
        return np.concatenate(
            [model.policy.parameters_to_vector(), model.rollout_buffer.target_atoms.ravel()]
        )

    np.testing.assert_array_equal(train(), train())


def test_vecnormalize_and_callable_schedules():
    env = VecNormalize(dict_env(), norm_obs=True, norm_reward=True)
    model = HuRiPPO(
        "MlpPolicy",
        env,
        learning_rate=lambda progress: 1e-3 * progress,
        clip_range=lambda p: 0.3 * p,
        **SMALL,
    )
    recorder = KeyRecorder()
    model.set_logger(Logger(folder=None, output_formats=[recorder]))
    model.learn(192)
    # Updates happen at progress remaining 1 - 64/192 and 1 - 128/192.
    np.testing.assert_allclose(recorder.records["train/learning_rate"], [1e-3 * 2 / 3, 1e-3 / 3])
    np.testing.assert_allclose(recorder.records["train/clip_range"], [0.3 * 2 / 3, 0.3 / 3])
    assert env.obs_rms["critic"].count > 1


@pytest.mark.skipif(not th.cuda.is_available(), reason="needs a CUDA device")
def test_cuda_device():
    model = HuRiPPO("MlpPolicy", dict_env(), device="cuda", **SMALL).learn(64)
    assert model.policy.rnd.predictor[0].weight.is_cuda


# --- bad input --------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("kwargs", "name"),
    [
        (dict(method="huri-lite"), "method"),
        (dict(n_quantiles=1), "n_quantiles"),
        (dict(iqr_thresholds=(0.7, 0.3)), "iqr_thresholds"),
        (dict(sr_lambda=1.5), "sr_lambda"),
        (dict(distortion="exponential"), "distortion"),
        (dict(cvar_alpha=0.0), "cvar_alpha"),
        (dict(cvar_alpha=1.2, method="huri-cvar0.5"), "cvar_alpha"),
        (dict(batch_size=1), "batch_size"),
        (dict(n_minibatches=200), "n_minibatches"),
        (dict(gamma=1.5), "gamma"),
        (dict(method="huri-baseline", use_rnd=True), "use_rnd"),
        (dict(n_quantiles=16, policy_kwargs=dict(n_quantiles=8)), "n_quantiles"),
        (dict(method="huri-baseline", policy_kwargs=dict(n_quantiles=8)), "n_quantiles"),
        (dict(rnd_kwargs=dict(output_dim=8), policy_kwargs=dict(rnd_kwargs={})), "rnd_kwargs"),
        (dict(expectation_loss="self"), "expectation_loss"),
        (dict(desired_kl=0.0), "desired_kl"),
        (dict(iqr_risk_levels=(1.0, 0.0)), "iqr_risk_levels"),
    ],
)
def test_bad_hyperparameters_raise_value_errors_naming_them(kwargs, name):
    with pytest.raises(ValueError, match=name):
        HuRiPPO("MlpPolicy", "Pendulum-v1", n_steps=64, **kwargs)


class TupleActionEnv(gym.Env):
    observation_space = spaces.Box(-1, 1, (2,), np.float32)
    action_space = spaces.Tuple((spaces.Discrete(2), spaces.Discrete(3)))

    def reset(self, *, seed=None, options=None):
        return np.zeros(2, np.float32), {}

    def step(self, action):
        return np.zeros(2, np.float32), 0.0, False, False, {}


def test_unsupported_action_space_fails_clearly():
    with pytest.raises(ValueError, match="action space"):
        HuRiPPO("MlpPolicy", DummyVecEnv([TupleActionEnv]))
