"""Go2Like-v0: the quadruped on the shared step, with legged_gym's task (zerith_gym.go2like.task)."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import zerith_gym  # noqa: F401
from zerith_gym.core.task import TaskState
from zerith_gym.go2like import constants as quad
from zerith_gym.go2like import task as lg
from zerith_gym.sb3.vec_env import make_vec_env


def test_go2like_passes_gymnasiums_checker_and_stands_still_with_zero_actions() -> None:
    env = gym.make("Go2Like-v0", scenario="nominal", command=(0.0, 0.0, 0.0))
    check_env(env.unwrapped, skip_render_check=True)
    obs, _ = env.reset(seed=3)
    assert obs["policy"].shape == (lg.POLICY_SIZE,) and obs["critic"].shape == (lg.CRITIC_SIZE,)
    for _ in range(250):
        obs, reward, terminated, truncated, info = env.step(np.zeros(12))
        assert not (terminated or truncated) and reward >= 0.0
    policy = obs["policy"]
    gravity = policy[6:9]
    np.testing.assert_allclose(gravity, [0.0, 0.0, -1.0], atol=0.02)  # upright
    heights = policy[-len(lg.HEIGHT_POINTS) :]
    np.testing.assert_allclose(heights, quad.STANDING_HEIGHT, atol=0.03)  # flat ground under the trunk
    assert set(info["reward_terms"]) == set(lg.DEFAULT_REWARD_WEIGHTS)


def _rollout(env, steps: int, seed: int) -> list[np.ndarray]:
    rng = np.random.default_rng(seed)
    obs = env.reset()
    record = [obs["policy"].copy(), obs["critic"].copy()]
    for _ in range(steps):
        obs, reward, done, _ = env.step(rng.uniform(-1, 1, (env.num_envs, 12)).astype(np.float32))
        record += [obs["policy"].copy(), obs["critic"].copy(), reward.copy(), done.copy()]
    return record


def test_the_same_transitions_with_any_number_of_worker_processes() -> None:
    runs = []
    for workers in (0, 1):
        env = make_vec_env(
            16, seed=7, robot="go2like", scenario="quadruped-train", episode_steps=60, workers=workers
        )
        try:
            runs.append(_rollout(env, 130, seed=1))
        finally:
            env.close()
    for a, b in zip(*runs, strict=True):
        np.testing.assert_array_equal(a, b)


def test_a_vec_env_of_quadrupeds_steps_as_single_envs_seeded_alike() -> None:
    venv = make_vec_env(3, seed=11, robot="go2like", episode_steps=40)
    singles = [gym.make("Go2Like-v0", episode_steps=40).unwrapped for _ in range(3)]
    rng = np.random.default_rng(0)
    batch_obs = venv.reset()
    single_obs = [env.reset(seed=11 + i)[0] for i, env in enumerate(singles)]
    for step in range(30):
        for i in range(3):
            np.testing.assert_array_equal(
                batch_obs["policy"][i], single_obs[i]["policy"], err_msg=f"step {step}"
            )
        actions = rng.uniform(-1, 1, (3, 12)).astype(np.float32)
        batch_obs, rewards, _, _ = venv.step(actions)
        for i, env in enumerate(singles):
            single_obs[i], reward, *_ = env.step(actions[i])
            assert rewards[i] == pytest.approx(reward, abs=1e-6)
    venv.close()


@pytest.mark.parametrize(
    ("options", "message"),
    [
        ({"robot": "zerith1"}, "simulates the go2like robot"),
        ({"scenario": "sudden-hands"}, "no 'hands' bodies"),
        ({"reward_weights": {"alive": 1.0}}, "valid terms: tracking_lin_vel"),
    ],
)
def test_bad_options_are_rejected_saying_what_is_allowed(options: dict, message: str) -> None:
    with pytest.raises(ValueError, match=message):
        gym.make("Go2Like-v0", **options)


def test_an_unknown_robot_is_rejected_listing_the_robots() -> None:
    with pytest.raises(ValueError, match="unknown robot 'spot'; valid robots: zerith1, go2like"):
        make_vec_env(2, robot="spot")


def test_non_finite_or_misshapen_actions_are_rejected() -> None:
    env = gym.make("Go2Like-v0")
    env.reset(seed=0)
    with pytest.raises(ValueError, match="NaN or infinite"):
        env.step(np.full(12, np.nan))
    with pytest.raises(ValueError, match="shape"):
        env.step(np.zeros(13))


def test_actions_reach_legged_gyms_clip_of_100_on_the_quadruped_and_1_on_zerith() -> None:
    """legged_gym clips actions at +-100 (+-25 rad with its 0.25 scale): a quadruped action of 2 commands
    0.5 rad from the default pose, not 0.25. Zerith-1 keeps its [-1, 1]."""
    from gymnasium import spaces

    from zerith_gym.core.task import action_targets

    quadruped, humanoid = gym.make("Go2Like-v0"), gym.make("Zerith1-v0")
    assert quadruped.action_space == spaces.Box(-100.0, 100.0, (12,), np.float32)
    assert humanoid.action_space == spaces.Box(-1.0, 1.0, (12,), np.float32)
    action = np.r_[np.full(6, 2.0), np.full(6, -150.0)]
    for env, applied in (
        (quadruped, np.r_[np.full(6, 2.0), np.full(6, -100.0)]),
        (humanoid, np.r_[np.ones(6), -np.ones(6)]),
    ):
        env.reset(seed=0)
        env.step(action)
        task = env.unwrapped.task
        np.testing.assert_array_equal(task.state.actions[0, 0], applied)
    targets = action_targets(quadruped.unwrapped.task.state.actions, quad.GO2LIKE)
    np.testing.assert_allclose(targets[0, 0, :6] - quad.DEFAULT_JOINT_POS[:6], 0.5)
    venv = make_vec_env(2, robot="go2like", workers=0)
    assert venv.action_space == quadruped.action_space
    venv.reset()
    venv.step(np.tile(action, (2, 1)))
    np.testing.assert_array_equal(
        venv.robots.task.state.actions[:, 0], np.tile(action.clip(-100, 100), (2, 1))
    )


def test_feet_air_time_pays_legged_gyms_formula_at_each_touchdown() -> None:
    """Random contact sequences through `judge`, against legged_gym's loop written out here."""
    rng = np.random.default_rng(0)
    n, steps = 6, 80
    contacts = rng.random((steps, n, 4)) < 0.6
    command = np.tile([0.5, 0.0, 0.0], (n, 1))
    command[0] = 0.05  # too slow: the term pays nothing
    env = gym.make("Go2Like-v0").unwrapped
    constants = env.task.constants
    state = TaskState.zeros(n, lg.QUADRUPED_TASK)._replace(command=command)
    readings = _still_readings(n)
    air, last = np.zeros((n, 4)), np.zeros((n, 4), dtype=bool)
    for contact in contacts:
        readings = readings._replace(foot_force=np.repeat(contact * 50.0, 3, axis=1))
        judged, state = lg.judge(state, readings, np.zeros(n, dtype=int), None, constants)
        touching = contact | last
        first = (air > 0) & touching
        air = air + 0.02
        expected = ((air - 0.5) * first).sum(axis=1) * (np.hypot(command[:, 0], command[:, 1]) > 0.1)
        air, last = air * ~touching, contact
        column = list(lg.DEFAULT_REWARD_WEIGHTS).index("feet_air_time")
        np.testing.assert_allclose(judged.terms[:, column], expected * 1.0 * 0.02, atol=1e-12)
        np.testing.assert_allclose(judged.reward, np.maximum(judged.terms.sum(axis=1), 0.0))


def _still_readings(n: int) -> quad.Sensors:
    """Sensor readings of n quadrupeds standing still in the default pose on flat ground."""
    zeros = np.zeros((n, 3))
    return quad.Sensors(
        base_pos=np.tile([0.0, 0.0, quad.STANDING_HEIGHT], (n, 1)),
        base_heading=np.tile([1.0, 0.0, 0.0], (n, 1)),
        base_up=np.tile([0.0, 0.0, 1.0], (n, 1)),
        base_linvel=zeros,
        base_angvel=zeros,
        joint_pos=np.tile(quad.DEFAULT_JOINT_POS, (n, 1)),
        joint_vel=np.zeros((n, 12)),
        joint_torque=np.zeros((n, 12)),
        foot_pos=np.zeros((n, 12)),
        foot_linvel=np.zeros((n, 12)),
        foot_force=np.zeros((n, 12)),
        base_contact=np.zeros((n, 1)),
        leg_contact=np.zeros((n, 8)),
    )


def test_collisions_limits_and_falls_read_the_contact_sensors_and_joint_ranges() -> None:
    env = gym.make("Go2Like-v0").unwrapped
    constants = env.task.constants
    n = 3
    state = TaskState.zeros(n, lg.QUADRUPED_TASK)
    readings = _still_readings(n)
    leg_contact = np.zeros((n, 8))
    leg_contact[1, [0, 3, 5]] = [1, 2, 1]  # three links of robot 1 touch the ground, one twice
    base_contact = np.array([[0.0], [0.0], [1.0]])
    low, _ = constants.soft_limits
    joint_pos = np.tile(quad.DEFAULT_JOINT_POS, (n, 1))
    joint_pos[0, 2] = low[2] - 0.1  # robot 0's FL calf 0.1 rad below its soft limit
    readings = readings._replace(leg_contact=leg_contact, base_contact=base_contact, joint_pos=joint_pos)
    judged, _ = lg.judge(state, readings, np.zeros(n, dtype=int), None, constants)
    names = list(lg.DEFAULT_REWARD_WEIGHTS)
    terms = judged.terms / (np.array(list(lg.DEFAULT_REWARD_WEIGHTS.values())) * 0.02)
    np.testing.assert_allclose(terms[:, names.index("collision")], [0.0, 3.0, 0.0])
    np.testing.assert_allclose(terms[:, names.index("dof_pos_limits")], [0.1, 0.0, 0.0], atol=1e-12)
    np.testing.assert_array_equal(judged.fall, [False, False, True])
    # soft limits at 90% of each joint's range, centred
    centre, half = quad.JOINT_RANGE.mean(axis=1), np.diff(quad.JOINT_RANGE, axis=1)[:, 0] / 2
    np.testing.assert_allclose(low, centre - 0.9 * half)


def test_training_logs_the_quadrupeds_reward_terms(tmp_path) -> None:
    """`RewardTermsLogger` reads the env's own terms (legged_gym's), not Zerith-1's."""
    import csv

    from stable_baselines3.common.logger import configure

    from sb3_huri import HuRiPPO
    from zerith_gym.sb3.callbacks import RewardTermsLogger

    env = make_vec_env(4, seed=0, robot="go2like", episode_steps=10, workers=0)
    model = HuRiPPO("MultiInputPolicy", env, n_steps=16, batch_size=64, n_epochs=1, seed=0)
    model.set_logger(configure(str(tmp_path), ["csv"]))
    model.learn(64, callback=RewardTermsLogger())
    with open(tmp_path / "progress.csv") as file:
        row = next(csv.DictReader(file))
    assert {f"terms/{name}" for name in lg.DEFAULT_REWARD_WEIGHTS} <= set(row)
    assert float(row["terms/tracking_lin_vel"]) > 0.0 and "terms/alive" not in row
    env.close()
