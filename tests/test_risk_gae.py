"""The two readings of a TD error's risk levels (``sb3_huri.common.risk_gae``): against a loop written from
their definitions, against SB3's GAE on a real rollout, with one level for every state (where they agree),
and the method that trains on each step's own level."""

import numpy as np
import pytest
import torch as th
from huri_helpers import SMALL, dict_env

from sb3_huri import METHODS, HuRiPPO
from sb3_huri.common import wang_weights
from sb3_huri.common.risk_gae import risk_gae
from sb3_huri.huri.risk import RiskModel

pytestmark = pytest.mark.filterwarnings("ignore::sb3_huri.UnnormalizedRewardWarning")

T, E, N, GAMMA, LAMBDA = 12, 3, 8, 0.97, 0.9


def random_rollout(seed: int = 0, levels: str = "varying") -> dict:
    """A rollout with terminals, time-outs and (``varying``) a Wang level per state in [-1, 2]."""
    rng = np.random.default_rng(seed)
    atoms = np.sort(rng.normal(size=(T, E, N)), axis=-1)
    betas = rng.uniform(-1, 2, size=(T, E)) if levels == "varying" else np.full((T, E), 0.7)
    ends = rng.random((T, E)) < 0.25
    time_outs = ends & (rng.random((T, E)) < 0.5)
    final_betas = rng.uniform(-1, 2, size=(T, E)) if levels == "varying" else np.full((T, E), 0.7)
    last_beta = rng.uniform(-1, 2, size=E) if levels == "varying" else np.full(E, 0.7)
    return dict(
        rewards=rng.normal(size=(T, E)),
        atoms=atoms,
        weights=wang_weights(th.as_tensor(betas), N).numpy(),
        episode_starts=np.concatenate([np.ones((1, E)), ends[:-1]]).astype(np.float32),
        last_atoms=np.sort(rng.normal(size=(E, N)), axis=-1),
        last_weights=wang_weights(th.as_tensor(last_beta), N).numpy(),
        last_dones=ends[-1].astype(np.float32),
        bootstrap_atoms=np.where(time_outs[..., None], np.sort(rng.normal(size=(T, E, N)), axis=-1), 0.0),
        bootstrap_weights=wang_weights(th.as_tensor(final_betas), N).numpy() * time_outs[..., None],
    )


def looped_advantages(rollout: dict, td_level: str, gamma: float = GAMMA, lam: float = LAMBDA) -> np.ndarray:
    """GAE written out step by step and robot by robot from the readings' definitions."""
    r = rollout
    n_steps, n_envs = np.shape(r["rewards"])
    bootstrap_atoms = r.get("bootstrap_atoms")
    advantages = np.zeros((n_steps, n_envs))
    for env in range(n_envs):
        running = 0.0
        for t in reversed(range(n_steps)):
            own = r["weights"][t, env]
            if t == n_steps - 1:
                next_atoms, continues = r["last_atoms"][env], 1.0 - r["last_dones"][env]
                next_weights = r["last_weights"][env]
            else:
                next_atoms, continues = r["atoms"][t + 1, env], 1.0 - r["episode_starts"][t + 1, env]
                next_weights = r["weights"][t + 1, env]
            level_there = own if td_level == "step" else next_weights
            reward = r["rewards"][t, env]
            if bootstrap_atoms is not None:
                level_final = own if td_level == "step" else r["bootstrap_weights"][t, env]
                reward += gamma * float(level_final @ bootstrap_atoms[t, env])
            value_here = float(own @ r["atoms"][t, env])
            delta = reward + gamma * continues * float(level_there @ next_atoms) - value_here
            running = delta + gamma * lam * continues * running
            advantages[t, env] = running
    return advantages


@pytest.mark.parametrize("td_level", ["state", "step"])
def test_each_reading_is_its_definition(td_level):
    rollout = random_rollout()
    computed = risk_gae(**rollout, gamma=GAMMA, gae_lambda=LAMBDA, td_level=td_level)
    np.testing.assert_allclose(computed, looped_advantages(rollout, td_level), rtol=1e-5, atol=1e-5)


def test_the_readings_differ_when_levels_vary_and_agree_when_they_do_not():
    varying, constant = random_rollout(levels="varying"), random_rollout(levels="constant")
    readings = {
        name: {
            level: risk_gae(**rollout, gamma=GAMMA, gae_lambda=LAMBDA, td_level=level)
            for level in ("state", "step")
        }
        for name, rollout in (("varying", varying), ("constant", constant))
    }
    np.testing.assert_allclose(readings["constant"]["state"], readings["constant"]["step"], atol=1e-5)
    assert np.abs(readings["varying"]["state"] - readings["varying"]["step"]).max() > 0.1


def test_with_lambda_one_the_state_reading_is_a_baseline_and_the_step_reading_adds_the_level_changes():
    """With ``gae_lambda = 1`` the state reading is the discounted return minus the state's own value (its
    levels only shift the baseline); the step reading adds, at each later state of the episode, its value at
    the previous state's level minus its value at its own."""
    rollout = random_rollout(seed=3)
    rollout["bootstrap_atoms"] = rollout["bootstrap_weights"] = None  # terminals only
    r = rollout
    value = np.einsum("ten,ten->te", r["weights"], r["atoms"])
    values = np.concatenate([value, np.einsum("en,en->e", r["last_weights"], r["last_atoms"])[None]])
    weights = np.concatenate([r["weights"], r["last_weights"][None]])
    states = np.concatenate([r["atoms"], r["last_atoms"][None]])
    continued = 1.0 - np.concatenate([r["episode_starts"][1:], r["last_dones"][None]])  # after step t
    expected = {"state": np.zeros((T, E)), "step": np.zeros((T, E))}
    for env in range(E):
        for t in range(T):
            discounted_return, changes, discount, j = 0.0, 0.0, 1.0, t
            while True:
                discounted_return += discount * r["rewards"][j, env]
                if not continued[j, env]:
                    break
                discount *= GAMMA
                j += 1
                previous_level = float(weights[j - 1, env] @ states[j, env])
                changes += discount * (previous_level - values[j, env])
                if j == T:
                    discounted_return += discount * values[T, env]
                    break
            expected["state"][t, env] = discounted_return - values[t, env]
            expected["step"][t, env] = discounted_return - values[t, env] + changes
    for td_level, wanted in expected.items():
        computed = risk_gae(**rollout, gamma=GAMMA, gae_lambda=1.0, td_level=td_level)
        np.testing.assert_allclose(computed, wanted, rtol=1e-5, atol=1e-5, err_msg=td_level)


def test_unknown_readings_and_missing_final_levels_are_refused():
    rollout = random_rollout()
    with pytest.raises(ValueError, match=r"td_level 'next'.*\['state', 'step'\]"):
        risk_gae(**rollout, gamma=GAMMA, gae_lambda=LAMBDA, td_level="next")
    rollout["bootstrap_weights"] = None
    with pytest.raises(ValueError, match="bootstrap_weights"):
        risk_gae(**rollout, gamma=GAMMA, gae_lambda=LAMBDA, td_level="state")
    np.testing.assert_allclose(  # the step reading values final states at the step's level: none needed
        risk_gae(**rollout, gamma=GAMMA, gae_lambda=LAMBDA, td_level="step"),
        looped_advantages(random_rollout(), "step"),
        atol=1e-5,
    )


def fresh_rollout(td_level: str) -> HuRiPPO:
    """A percentile-band model reading ``td_level`` that learned one update, with a second rollout collected
    into its buffer (time order, before ``get()``), on an env whose 13-step episodes time out in it."""
    env = dict_env(n_envs=3, max_episode_steps=13)
    model = HuRiPPO("MlpPolicy", env, method="huri-percentile", td_level=td_level, seed=0, **SMALL)
    model.learn(96)
    callback = model._init_callback(None)
    callback.on_training_start(locals(), globals())
    assert model.collect_rollouts(model.env, callback, model.rollout_buffer, model.n_steps)
    return model


@pytest.mark.parametrize("td_level", ["state", "step"])
def test_a_rollout_trains_on_its_reading_and_gives_the_other(td_level):
    """The state reading through the buffer is SB3's GAE on the per-state values; a model reading per step
    trains on the step reading; both come from the buffer's own atoms, levels and time-outs and agree with
    the loop written from their definitions."""
    model = fresh_rollout(td_level)
    buffer = model.rollout_buffer
    assert buffer.has_time_outs and np.ptp(buffer.risk) > 0  # levels that vary, episodes cut short
    own_reading = td_level
    assert buffer.td_level == own_reading == model.risk_model.td_level == model.td_level
    np.testing.assert_allclose(buffer.advantages, buffer.advantages_under(own_reading), rtol=1e-4, atol=1e-5)
    np.testing.assert_allclose(buffer.returns, buffer.advantages + buffer.values, rtol=1e-5, atol=1e-5)
    other_reading = "step" if own_reading == "state" else "state"
    other = buffer.advantages_under(other_reading)
    assert np.abs(other - buffer.advantages).max() > 1e-3
    arrays = dict(
        rewards=buffer.rewards, atoms=buffer.atoms, weights=buffer.distortion_weights,
        episode_starts=buffer.episode_starts, last_atoms=buffer.last_atoms, last_weights=buffer.last_weights,
        last_dones=buffer.last_dones, bootstrap_atoms=buffer.bootstrap_atoms,
        bootstrap_weights=buffer.bootstrap_weights,
    )  # fmt: skip
    for reading, advantages in ((own_reading, buffer.advantages), (other_reading, other)):
        looped = looped_advantages(arrays, reading, model.gamma, model.gae_lambda)
        np.testing.assert_allclose(advantages, looped, rtol=1e-4, atol=1e-4, err_msg=reading)


def test_every_method_reads_per_state_and_a_model_saves_its_reading(tmp_path):
    def risk_of(method, **arguments):
        return HuRiPPO("MlpPolicy", None, method=method, _init_setup_model=False, **arguments).risk_model

    assert all(preset.td_level == "state" for preset in METHODS.values())
    assert risk_of("huri-percentile", td_level="step").td_level == "step"
    model = HuRiPPO("MlpPolicy", dict_env(), method="huri", td_level="step", **SMALL)
    model.save(tmp_path / "model.zip")
    loaded = HuRiPPO.load(tmp_path / "model.zip")
    assert loaded.td_level == loaded.rollout_buffer.td_level == "step"


def test_a_scalar_critic_or_an_unknown_reading_is_refused():
    with pytest.raises(ValueError, match="td_level need a quantile critic"):
        HuRiPPO("MlpPolicy", dict_env(), method="huri-baseline", td_level="step")
    with pytest.raises(ValueError, match=r"Unknown td_level 'next'"):
        HuRiPPO("MlpPolicy", dict_env(), method="huri", td_level="next")
    with pytest.raises(ValueError, match="a scalar critic"):
        RiskModel(
            distributional=False, distortion="wang", use_iqr=False, use_rnd=False, n_quantiles=1,
            wang_beta=0.0, cvar_alpha=1.0, iqr_thresholds=(0.3, 0.7), iqr_risk_levels=(-1, 0, 1),
            td_level="step",
        )  # fmt: skip
