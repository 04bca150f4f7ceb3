"""The randomization curriculum: scaled scenarios, scenario changes in a running env, the SB3 callback."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from stable_baselines3 import PPO

import zerith_gym
from zerith_gym import Zerith1Env
from zerith_gym.core.observations import layout_slices
from zerith_gym.core.randomization import NOMINAL
from zerith_gym.core.scenarios import SCENARIOS, scaled_scenario
from zerith_gym.sb3.callbacks import RandomizationCurriculum
from zerith_gym.zerith1.observations import CRITIC_LAYOUT, critic_in_units


def test_randomization_scale_zero_is_nominal_and_one_is_the_scenario() -> None:
    scenario = SCENARIOS["train"]
    none, full = scaled_scenario(scenario, 0.0), scaled_scenario(scenario, 1.0)
    assert none.randomization == NOMINAL
    assert none.force.magnitude == (0.0, 0.0)
    assert full.randomization == scenario.randomization and full.force == scenario.force
    half = scaled_scenario(scenario, 0.5).randomization
    assert half.friction == pytest.approx((0.55, 1.25))  # 1 + 0.5 ((0.1, 1.5) - 1)
    assert half.push_velocity == pytest.approx((0.0, 0.25))
    assert half.observation_noise == pytest.approx(0.5)
    assert half.push_interval_s == scenario.randomization.push_interval_s
    assert dataclasses.replace(scaled_scenario(scenario, 0.5), name="train").command_ranges == (
        scenario.command_ranges
    )
    with pytest.raises(ValueError, match=r"in \[0, 1\]"):
        scaled_scenario(scenario, 1.5)


def test_schedule_rises_in_stages_and_resumes_from_the_model_steps() -> None:
    curriculum = RandomizationCurriculum(steps=400, stages=4)
    assert [curriculum.scheduled_stage(t) for t in (0, 99, 100, 250, 399, 400, 10_000)] == [
        0,
        0,
        1,
        2,
        3,
        4,
        4,
    ]
    assert RandomizationCurriculum(steps=0, stages=4).scheduled_stage(0) == 4
    assert RandomizationCurriculum(steps=4e6).steps == 4_000_000  # YAML floats
    for kwargs, match in [
        (dict(steps=-1), "non-negative"),
        (dict(steps=10, stages=0), "stages"),
        (dict(steps=10, max_fall_rate=2.0), "max_fall_rate"),
    ]:
        with pytest.raises(ValueError, match=match):
            RandomizationCurriculum(**kwargs)


@pytest.mark.parametrize("workers", [0, 2])
def test_a_running_env_follows_a_new_scenario_from_the_next_resets(workers: int) -> None:
    env = zerith_gym.make_vec_env(4, seed=0, episode_steps=5, workers=workers)
    env.reset()
    env.set_scenario(scaled_scenario(SCENARIOS["train"], 0.0))
    assert env.get_attr("scenario")[0].randomization == NOMINAL
    obs = None
    for _ in range(5):  # every robot times out at step 5 and restarts with nominal parameters
        obs, _, dones, infos = env.step(np.zeros((4, 12)))
    assert dones.all() and not any(info["external_force"].any() for info in infos)
    friction = critic_in_units(obs["critic"])[:, layout_slices(CRITIC_LAYOUT)["domain_friction"]]
    np.testing.assert_allclose(friction, 1.0, rtol=1e-6)
    with pytest.raises(ValueError, match="another terrain"):
        env.set_scenario("uneven")
    env.close()

    single = Zerith1Env(episode_steps=5)
    single.reset(seed=0)
    single.set_scenario("nominal")
    assert single.scenario.name == "nominal"


def test_curriculum_callback_changes_the_training_scenario_by_timesteps() -> None:
    env = zerith_gym.make_vec_env(4, seed=0, obs_mode="policy", episode_steps=16, workers=2)
    model = PPO(
        "MlpPolicy", env, n_steps=16, batch_size=32, n_epochs=1, seed=0, policy_kwargs=dict(net_arch=[8])
    )
    curriculum = RandomizationCurriculum(steps=128, stages=2)
    model.learn(128, callback=curriculum)  # rollouts start at 0 (scale 0) and 64 (scale 0.5)
    assert curriculum.scale == 0.5 and env.scenario.randomization.friction == pytest.approx((0.55, 1.25))
    model.learn(128, callback=curriculum, reset_num_timesteps=False)  # at 128 and 192: the full scenario
    assert curriculum.scale == 1.0 and env.scenario == SCENARIOS["train"]
    resumed = RandomizationCurriculum(steps=128, stages=2)  # a resumed run starts from the model's steps
    model.learn(64, callback=resumed, reset_num_timesteps=False)
    assert resumed.scale == 1.0
    env.close()


def test_fall_rate_gate_holds_a_stage_until_the_robots_stop_falling() -> None:
    from types import SimpleNamespace

    class Env:
        """Stands for a training VecEnv: records the scenarios it is given."""

        def __init__(self) -> None:
            self.scenarios = []
            self.unwrapped = self

        def set_scenario(self, scenario) -> None:
            self.scenarios.append(scenario)

        def get_attr(self, name: str) -> list:
            return [SCENARIOS["train"]]

    env = Env()
    model = SimpleNamespace(
        num_timesteps=0, get_env=lambda: env, logger=SimpleNamespace(record=lambda *a: None)
    )
    curriculum = RandomizationCurriculum(steps=100, stages=4, max_fall_rate=0.25, gate_episodes=4)
    curriculum.init_callback(model)
    curriculum.on_training_start({}, {})

    def rollout(timesteps: int, falls: list[bool]) -> float:
        """A rollout starting at `timesteps` whose ended episodes fell or not; the scale it trained at."""
        model.num_timesteps = timesteps
        curriculum.on_rollout_start()
        curriculum.locals = {"infos": [{"fall": f} for f in falls], "dones": [True] * len(falls)}
        curriculum._on_step()
        return curriculum.scale

    # The scale a rollout trains at is decided by the episodes that ended before it.
    assert rollout(0, [True, True]) == 0.0
    assert rollout(90, [True, False]) == 0.0  # the schedule says 0.75, but 2 episodes are too few to judge
    assert rollout(91, [False]) == 0.0  # 3 of the last 4 fell
    assert rollout(92, [False]) == 0.0  # 2 of the last 4
    assert rollout(93, [False]) == 0.25  # 1 of the last 4: one stage up, one stage at a time
    assert rollout(200, [False, False, False]) == 0.25  # the new stage's window holds one episode
    assert rollout(300, []) == 0.5  # 4 episodes at this stage, none fell
    assert rollout(400, []) == 0.5  # no new episode: no evidence, the stage holds
    assert [s.name for s in env.scenarios] == ["trainx0", "trainx0.25", "trainx0.5"]


def test_fall_rate_gate_is_not_passed_by_one_lucky_rollout() -> None:
    """Rollouts of a few robots often end a few episodes without a fall at a high fall rate; the gate
    judges the stage's last `gate_episodes` episodes, so such a rollout does not move the stage."""
    from types import SimpleNamespace

    env = SimpleNamespace(set_scenario=lambda scenario: None, get_attr=lambda name: [SCENARIOS["train"]])
    env.unwrapped = env
    model = SimpleNamespace(
        num_timesteps=0, get_env=lambda: env, logger=SimpleNamespace(record=lambda *a: None)
    )
    curriculum = RandomizationCurriculum(steps=100, stages=4, max_fall_rate=0.2, gate_episodes=50)
    curriculum.init_callback(model)
    curriculum.on_training_start({}, {})
    rng = np.random.default_rng(0)
    for rollout in range(200):  # a fall rate of 0.5, 3 episodes per rollout
        model.num_timesteps = 10 * rollout  # the schedule alone would be at full scale from step 100
        curriculum.on_rollout_start()
        falls = rng.random(3) < 0.5
        curriculum.locals = {"infos": [{"fall": bool(f)} for f in falls], "dones": [True] * 3}
        curriculum._on_step()
    assert curriculum.scale == 0.0
    with pytest.raises(ValueError, match="gate_episodes must be a positive integer"):
        RandomizationCurriculum(steps=100, gate_episodes=0)


def test_update_threads_switch_by_phase_and_restore() -> None:
    import torch as th
    from stable_baselines3.common.callbacks import ConvertCallback

    from zerith_gym.sb3.callbacks import UpdateThreads

    env = zerith_gym.make_vec_env(2, seed=0, obs_mode="policy", episode_steps=16, workers=0)
    model = PPO(
        "MlpPolicy", env, n_steps=16, batch_size=32, n_epochs=1, seed=0, policy_kwargs=dict(net_arch=[8])
    )
    seen = {"collect": set(), "update": set()}
    train = model.train

    def recording_train() -> None:
        seen["update"].add(th.get_num_threads())
        train()

    model.train = recording_train
    before = th.get_num_threads()
    th.set_num_threads(3)
    try:

        def during_rollout(locals_, globals_) -> bool:
            last = locals_["n_steps"] + 1 == locals_["n_rollout_steps"]
            seen["update" if last else "collect"].add(th.get_num_threads())
            return True

        model.learn(64, callback=[UpdateThreads(collect=1, update=2), ConvertCallback(during_rollout)])
        assert seen == {"collect": {1}, "update": {2}}
        assert th.get_num_threads() == 3  # restored
    finally:
        th.set_num_threads(before)
    with pytest.raises(ValueError, match="positive integer"):
        UpdateThreads(collect=0)


def test_update_threads_give_huri_rollout_end_work_the_update_threads() -> None:
    """HuRiPPO's risk assessment of the rollout and its RND fit run before `on_rollout_end` reaches user
    callbacks: they get the update's threads, the policy's per-step calls the collecting ones."""
    import torch as th
    from stable_baselines3.common.vec_env import VecNormalize

    from sb3_huri import HuRiPPO
    from zerith_gym.sb3.callbacks import UpdateThreads

    env = VecNormalize(zerith_gym.make_vec_env(2, seed=0, episode_steps=16, workers=0))
    model = HuRiPPO("MultiInputPolicy", env, n_steps=16, n_epochs=1, seed=0, policy_kwargs=dict(net_arch=[8]))
    assert model.policy.rnd is not None
    seen: dict[str, set[int]] = {"act": set(), "finish": set(), "rnd fit": set()}

    def recording(name, method):
        def call(*args, **kwargs):
            seen[name].add(th.get_num_threads())
            return method(*args, **kwargs)

        return call

    model.policy.forward = recording("act", model.policy.forward)
    model._finish_rollout = recording("finish", model._finish_rollout)
    model.policy.rnd.fit = recording("rnd fit", model.policy.rnd.fit)
    before = th.get_num_threads()
    try:
        model.learn(64, callback=UpdateThreads(collect=1, update=2))
    finally:
        th.set_num_threads(before)
    assert seen == {"act": {1}, "finish": {2}, "rnd fit": {2}}
