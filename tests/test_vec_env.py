"""ZerithVecEnv: the same transitions as single envs, SB3's VecEnv contract, and training on it."""

from __future__ import annotations

import numpy as np
import pytest
from stable_baselines3 import PPO
from stable_baselines3.common.monitor import Monitor
from stable_baselines3.common.vec_env import VecEnv, VecMonitor, VecNormalize

import zerith_gym
from zerith_gym import Zerith1Env, ZerithVecEnv
from zerith_gym.zerith1.observations import CRITIC_SIZE, POLICY_SIZE

STEP_INFO_KEYS = ("fall", "sim_unstable", "lin_vel_error", "ang_vel_error", "external_force", "command")


def _obs_equal(batched, i: int | None, single) -> None:
    """Robot i's observation in a batched observation (or, with i None, one robot's) equals `single`."""
    if isinstance(single, dict):
        assert set(batched) == set(single)
        for key in single:
            value = batched[key] if i is None else batched[key][i]
            np.testing.assert_array_equal(value, single[key], err_msg=key)
    else:
        np.testing.assert_array_equal(batched if i is None else batched[i], single)


def _compare_with_single_envs(
    seed: int, steps: int, actions_of, physics_threads: int = 1, workers: int = 0, **env_kwargs
) -> dict[str, int]:
    """Step a ZerithVecEnv and single envs seeded seed + i side by side; assert every transition is equal."""
    num = 3
    venv = zerith_gym.make_vec_env(
        num, seed=seed, physics_threads=physics_threads, workers=workers, **env_kwargs
    )
    envs = [Zerith1Env(**env_kwargs) for _ in range(num)]
    obs = venv.reset()
    for i, env in enumerate(envs):
        single_obs, single_info = env.reset(seed=seed + i)
        _obs_equal(obs, i, single_obs)
        np.testing.assert_array_equal(venv.reset_infos[i]["command"], single_info["command"])
    counts = {"falls": 0, "time_outs": 0}
    for t in range(steps):
        actions = actions_of(t)
        obs, rewards, dones, infos = venv.step(actions)
        assert rewards.dtype == np.float32 and dones.dtype == bool
        for i, env in enumerate(envs):
            single_obs, reward, terminated, truncated, info = env.step(actions[i])
            assert rewards[i] == np.float32(reward)
            assert dones[i] == (terminated or truncated)
            assert infos[i]["reward_terms"] == info["reward_terms"]
            for key in STEP_INFO_KEYS:
                np.testing.assert_array_equal(infos[i][key], info[key], err_msg=key)
            assert infos[i]["TimeLimit.truncated"] == (truncated and not terminated)
            if terminated or truncated:
                counts["falls"] += terminated
                counts["time_outs"] += truncated
                _obs_equal(infos[i]["terminal_observation"], None, single_obs)
                assert infos[i]["episode_terms"] == info["episode_terms"]
                single_obs, reset_info = env.reset()
                np.testing.assert_array_equal(venv.reset_infos[i]["command"], reset_info["command"])
            else:
                assert "terminal_observation" not in infos[i] and "episode" not in infos[i]
            _obs_equal(obs, i, single_obs)
    venv.close()
    return counts


@pytest.mark.parametrize(("physics_threads", "workers"), [(1, 0), (2, 0), (3, 0), (1, 1), (1, 2), (2, 1)])
def test_batched_robots_reproduce_single_envs_through_falls_and_time_outs(physics_threads, workers):
    # Robot 0 holds still and times out after 60 steps; robots 1 and 2 act at random and fall. With 2 or 3
    # physics threads the robots are stepped in parallel groups, with workers in other processes beside a
    # slice in this one (each resetting its own robots), which must not change any transition.
    rng = np.random.default_rng(0)

    def actions_of(t: int) -> np.ndarray:
        actions = rng.uniform(-1.0, 1.0, size=(3, 12)).astype(np.float32)
        actions[0] = 0.0
        return actions

    counts = _compare_with_single_envs(
        7, 250, actions_of, physics_threads, workers, scenario="train", episode_steps=60
    )
    assert counts["falls"] >= 4 and counts["time_outs"] >= 4


@pytest.mark.parametrize(
    "env_kwargs",
    [
        dict(scenario="sudden-hands", obs_mode="policy"),
        dict(scenario="uneven", command=(0.3, 0.0, 0.1), workers=2),
        dict(scenario="load-friction", episode_steps=40),
    ],
)
def test_batched_robots_reproduce_single_envs_in_other_scenarios(env_kwargs):
    rng = np.random.default_rng(1)
    counts = _compare_with_single_envs(
        3, 120, lambda t: rng.uniform(-0.5, 0.5, size=(3, 12)).astype(np.float32), **env_kwargs
    )
    assert counts["falls"] + counts["time_outs"] >= 1


@pytest.mark.parametrize("workers", [0, 1])
def test_observations_handed_out_stay_as_they_were_through_later_steps_and_resets(workers):
    """The env hands out its observation arrays without copies (the task never writes into them again): next
    and terminal observations kept by the caller, as SB3 keeps `_last_obs`, must not change afterwards."""
    venv = zerith_gym.make_vec_env(4, seed=3, workers=workers, episode_steps=3)
    kept = [venv.reset()]
    resets = 0
    for _ in range(7):
        obs, _, dones, infos = venv.step(np.zeros((4, 12)))
        kept += [obs] + [infos[i]["terminal_observation"] for i in np.flatnonzero(dones)]
        resets += int(dones.sum())
    frozen = [{key: value.copy() for key, value in obs.items()} for obs in kept]
    for _ in range(4):
        venv.step(np.zeros((4, 12)))
    venv.close()
    assert resets >= 8
    for before, now in zip(frozen, kept, strict=True):
        for key in before:
            np.testing.assert_array_equal(now[key], before[key], err_msg=key)


def test_vec_env_contract_spaces_auto_reset_and_episode_statistics():
    venv = zerith_gym.make_vec_env(4, seed=0, episode_steps=30)
    assert isinstance(venv, VecEnv) and venv.num_envs == 4
    assert venv.observation_space["policy"].shape == (POLICY_SIZE,)
    assert venv.action_space.shape == (12,)
    obs = venv.reset()
    assert obs["policy"].shape == (4, POLICY_SIZE) and obs["policy"].dtype == np.float32
    assert obs["critic"].shape == (4, CRITIC_SIZE) and obs["critic"].dtype == np.float32
    returns, ends = np.zeros(4), []
    rng = np.random.default_rng(0)
    for _ in range(70):
        obs, rewards, dones, infos = venv.step(rng.uniform(-1, 1, size=(4, 12)))
        assert rewards.shape == (4,) and dones.shape == (4,)
        returns += rewards
        for i in np.flatnonzero(dones):
            episode = infos[i]["episode"]
            assert episode["r"] == pytest.approx(returns[i], abs=1e-4) and 1 <= episode["l"] <= 30
            assert infos[i]["terminal_observation"]["critic"].shape == (CRITIC_SIZE,)
            # after the auto-reset, the returned observation starts a new episode: last action is zero
            assert np.all(obs["policy"][i, 34:46] == 0.0)
            returns[i] = 0.0
            ends.append(episode["l"])
    assert 30 in ends  # time-outs at exactly episode_steps
    assert venv.env_is_wrapped(Monitor) == [True] * 4
    assert venv.env_is_wrapped(VecMonitor) == [False] * 4


def test_seeding_options_attributes_and_bad_input():
    venv = ZerithVecEnv(2, scenario="nominal", obs_mode="policy")
    assert venv.seed(5) == [5, 6]
    first = venv.reset()
    venv.seed(5)
    np.testing.assert_array_equal(venv.reset(), first)
    venv.set_options({"command": (0.4, 0.0, 0.0)})
    venv.reset()
    np.testing.assert_array_equal([info["command"] for info in venv.reset_infos], [[0.4, 0.0, 0.0]] * 2)
    assert venv.get_attr("options")[0].scenario == "nominal"
    assert venv.get_attr("obs_mode") == ["policy", "policy"]
    assert venv.get_attr("obs_mode", indices=[1]) == ["policy"]
    venv.set_attr("render_mode", None)
    with pytest.raises(ValueError, match="shared by all robots"):
        venv.set_attr("obs_mode", "dict", indices=[0])
    with pytest.raises(ValueError, match="action must have shape"):
        venv.step(np.zeros((3, 12)))
    with pytest.raises(ValueError, match="NaN or infinite"):
        venv.step(np.full((2, 12), np.nan))
    venv.set_options({"speed": 1.0})
    with pytest.raises(ValueError, match="valid options: command"):
        venv.reset()
    with pytest.raises(ValueError, match="valid scenarios"):
        ZerithVecEnv(2, scenario="moon")
    with pytest.raises(ValueError, match="valid values: dict, policy"):
        ZerithVecEnv(2, obs_mode="image")
    with pytest.raises(ValueError, match="positive integer"):
        ZerithVecEnv(0)
    with pytest.raises(ValueError, match="episode_steps"):
        ZerithVecEnv(2, episode_steps=0)
    with pytest.raises(ValueError, match="physics threads must be a positive integer"):
        ZerithVecEnv(2, physics_threads=0)
    with pytest.raises(ValueError, match=r"workers must be an integer in \[1, 1\]"):
        ZerithVecEnv(2, workers=2)
    with pytest.raises(ValueError, match=r"unknown ZerithVecEnv option.*'speed'.*valid options: scenario"):
        ZerithVecEnv(2, speed=1.0)


def test_closing_stops_the_physics_threads_and_the_env_still_steps():
    venv = ZerithVecEnv(4, scenario="nominal", obs_mode="policy", physics_threads=2, workers=0)
    venv.seed(3)
    venv.reset()
    actions = np.zeros((4, 12), dtype=np.float32)
    threaded = venv.step(actions)[0]
    pool = venv.robots.sim._pool
    venv.close()
    assert venv.workers == 0 and pool is not None and pool._shutdown and venv.robots.sim._pool is None
    after_close = venv.step(actions)[0]
    reference = ZerithVecEnv(4, scenario="nominal", obs_mode="policy")
    reference.seed(3)
    reference.reset()
    np.testing.assert_array_equal(reference.step(actions)[0], threaded)
    np.testing.assert_array_equal(reference.step(actions)[0], after_close)


def test_ppo_with_vec_normalize_and_huri_learn_on_the_batched_env():
    from sb3_huri import HuRiPPO

    env = VecNormalize(zerith_gym.make_vec_env(4, seed=0, obs_mode="policy", episode_steps=20))
    small = dict(n_steps=16, n_epochs=1, seed=0, policy_kwargs=dict(net_arch=[32]))
    ppo = PPO("MlpPolicy", env, batch_size=32, **small)
    ppo.learn(128)
    assert ppo.num_timesteps == 128 and len(ppo.ep_info_buffer) > 0  # episode statistics reached SB3's logger

    env = zerith_gym.make_vec_env(4, seed=0, episode_steps=20)
    huri = HuRiPPO("MlpPolicy", env, **small)
    huri.learn(128)
    assert huri.num_timesteps == 128 and huri.rollout_buffer.has_time_outs
    assert len(huri.ep_info_buffer) > 0 and np.isfinite(huri.rollout_buffer.advantages).all()


def test_reward_terms_of_every_robot_sum_to_its_reward():
    venv = zerith_gym.make_vec_env(4, seed=2, episode_steps=30, workers=2)
    venv.reset()
    rng = np.random.default_rng(2)
    sums = np.zeros(4)
    for _ in range(40):
        _, rewards, dones, infos = venv.step(rng.uniform(-1, 1, size=(4, 12)))
        for i, info in enumerate(infos):
            assert rewards[i] == pytest.approx(sum(info["reward_terms"].values()), rel=1e-6, abs=1e-6)
            sums[i] += sum(info["reward_terms"].values())
            if dones[i]:
                assert sum(info["episode_terms"].values()) == pytest.approx(sums[i], rel=1e-9, abs=1e-9)
                assert info["episode"]["r"] == pytest.approx(sums[i], abs=1e-5)
                sums[i] = 0.0
    venv.close()


def test_default_workers_follow_the_cores_and_the_robots(monkeypatch):
    from zerith_gym.cpu import workers

    monkeypatch.setattr(workers, "available_cores", lambda: 16)
    # one slice per core, the calling process stepping one of them, at least 8 robots a slice
    assert [workers.default_workers(n) for n in (1, 8, 15, 16, 32, 100, 1024)] == [0, 0, 0, 1, 3, 11, 15]
    monkeypatch.setattr(workers, "available_cores", lambda: 1)
    assert workers.default_workers(1024) == 0
    assert workers.default_workers(1024, cores=4) == 3


def test_worker_failures_and_closing_give_clear_errors():
    venv = ZerithVecEnv(4, scenario="nominal", obs_mode="policy", workers=2)
    venv.seed(0)
    venv.reset()
    venv.step(np.zeros((4, 12)))
    assert len(venv.robots._processes) == 2  # and a slice in this process
    venv.robots._processes[1].kill()
    venv.robots._processes[1].join()
    with pytest.raises(RuntimeError, match="worker process exited"):
        venv.step(np.zeros((4, 12)))
    with pytest.raises(RuntimeError, match="closed"):
        venv.step(np.zeros((4, 12)))
    assert not any(process.is_alive() for process in venv.robots._processes)

    venv = ZerithVecEnv(4, scenario="nominal", workers=2)
    venv.close()
    venv.close()  # closing twice is harmless
    with pytest.raises(RuntimeError, match="closed"):
        venv.reset()


def test_workers_end_when_the_process_that_made_them_is_killed():
    """A SIGKILL (or a SIGTERM the process does not handle) closes nothing: the workers must notice that
    their maker is gone instead of waiting on its pipes forever, holding the caller's output open."""
    import subprocess
    import sys
    import time

    script = (
        "import os, signal, numpy as np, zerith_gym\n"
        "env = zerith_gym.make_vec_env(4, seed=0, workers=2)\n"
        "env.reset(); env.step(np.zeros((4, 12)))\n"
        "print(' '.join(str(p.pid) for p in env.robots._processes), flush=True)\n"
        "os.kill(os.getpid(), signal.SIGKILL)\n"
    )
    run = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=120)
    assert run.returncode == -9, run.stderr
    workers = [int(pid) for pid in run.stdout.split()]
    assert len(workers) == 2

    def alive(pid: int) -> bool:
        try:
            with open(f"/proc/{pid}/stat") as f:
                return f.read().rsplit(")", 1)[1].split()[0] != "Z"  # a zombie has ended
        except FileNotFoundError:
            return False

    deadline = time.monotonic() + 10
    while any(alive(pid) for pid in workers) and time.monotonic() < deadline:
        time.sleep(0.2)
    assert not any(alive(pid) for pid in workers)


def test_reward_terms_logger_writes_each_term_per_rollout(tmp_path):
    import csv

    from stable_baselines3.common.logger import configure

    from zerith_gym.sb3.callbacks import RewardTermsLogger

    env = zerith_gym.make_vec_env(4, seed=0, obs_mode="policy", episode_steps=16, workers=0)
    model = PPO(
        "MlpPolicy", env, n_steps=16, batch_size=32, n_epochs=1, seed=0, policy_kwargs=dict(net_arch=[8])
    )
    model.set_logger(configure(str(tmp_path), ["csv"]))
    model.learn(128, callback=RewardTermsLogger())

    with open(tmp_path / "progress.csv") as f:
        rows = list(csv.DictReader(f))
    assert len(rows) == 2
    for row in rows:  # every episode lasts 16 steps or falls before: one rollout holds 4 or more endings
        assert 0.0 <= float(row["terms/fall_rate"]) <= 1.0 and float(row["terms/lin_vel_error"]) > 0.0
        assert 0.0 < float(row["terms/alive"]) <= 0.5 * 0.02 * 16 + 1e-9  # weight x dt x episode length
        assert all(f"terms/{name}" in row for name in zerith_gym.REWARD_NAMES)


def test_stepping_before_the_first_reset_is_a_clear_error():
    env = zerith_gym.make_vec_env(2, workers=0)
    with pytest.raises(RuntimeError, match="call reset\\(\\) before the first step"):
        env.step(np.zeros((2, 12)))
    env.reset()
    env.step(np.zeros((2, 12)))
    env.close()


def test_every_backend_keeps_the_robots_contract():
    """The CPU batch and the worker pool have every member of `core.contract.Robots` (MJX: test_mjx)."""
    import inspect

    from zerith_gym.core.contract import Robots, check_num_robots

    members = [name for name in vars(Robots) if not name.startswith("_")] + ["num_robots", "scenario"]
    for workers in (0, 1):
        env = zerith_gym.make_vec_env(4, seed=0, workers=workers)
        env.reset()
        for name in members:
            assert hasattr(env.robots, name), (type(env.robots).__name__, name)
        step = inspect.signature(env.robots.step)
        assert next(iter(step.parameters)) == "actions"
        env.close()
    for bad in (0, -1, 2.5, True, "4"):
        with pytest.raises(ValueError, match="the number of robots must be a positive integer"):
            check_num_robots(bad)


def test_the_worker_shared_block_holds_every_field_of_the_step_record():
    from zerith_gym.core.contract import BatchStep
    from zerith_gym.core.task import StepOutput
    from zerith_gym.cpu.workers import step_columns
    from zerith_gym.robots import ROBOT_TASKS

    for task in ROBOT_TASKS.values():
        out, batch = step_columns(task)
        assert list(out) == list(StepOutput._fields)
        assert ["out", *batch, "reward_names"] == list(BatchStep._fields)  # the names travel by value
        assert out["policy_obs"][1] == (task.policy_size,) and out["terms"][1] == (len(task.reward_names),)
