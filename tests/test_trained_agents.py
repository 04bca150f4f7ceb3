"""The shipped agents (Zerith-1's two, the quadruped's one) load and act, RL Zoo and the README's main
command find them, and the evaluation tools compute what they claim (gait measures)."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml
from stable_baselines3.common.vec_env import VecNormalize

import zerith_gym
from sb3_huri import HuRiPPO
from sb3_huri.runner.evaluation import TABLE1_SCENARIOS, gait_measures
from study.analyses import agents

REPO = Path(__file__).resolve().parents[1]
ENV_ID = "Zerith1-v0"
AGENTS = ("huri", "huri-baseline")
"""The shipped Zerith-1 agents' methods: each is in the folder of its RL Zoo algorithm, the method's name."""
SHIPPED = [(method, ENV_ID, "zerith1") for method in AGENTS] + [("huri", "Go2Like-v0", "go2like")]
"""Every shipped agent: method, env id and robot."""


@pytest.mark.parametrize(("method", "env_id", "robot"), SHIPPED)
def test_shipped_agent_has_rl_zoo_layout_and_is_small(method: str, env_id: str, robot: str) -> None:
    run = REPO / "trained_agents" / method / f"{env_id}_1"
    for name in (f"{env_id}.zip", f"{env_id}/vecnormalize.pkl", f"{env_id}/config.yml", f"{env_id}/args.yml"):
        assert (run / name).is_file(), name
    assert (run / f"{env_id}.zip").stat().st_size < 5_000_000
    assert (run / env_id / "vecnormalize.pkl").stat().st_size < 100_000
    args = yaml.safe_load((run / env_id / "args.yml").read_text())
    assert args["algo"] == method and args["env"] == env_id


@pytest.mark.parametrize(("method", "env_id", "robot"), SHIPPED)
def test_shipped_agent_stays_up_for_two_seconds_in_the_nominal_scenario(
    method: str, env_id: str, robot: str
) -> None:
    run = REPO / "trained_agents" / method / f"{env_id}_1"
    model = HuRiPPO.load(run / f"{env_id}.zip", device="cpu")
    assert model.method == method
    env = zerith_gym.make_vec_env(4, seed=0, scenario="nominal", command=(0.5, 0.0, 0.0), robot=robot)
    normalizer = VecNormalize.load(str(run / env_id / "vecnormalize.pkl"), env)
    normalizer.training = False
    obs = normalizer.reset()
    bound = env.action_space.high.max()  # 1 for Zerith-1, legged_gym's 100 for the quadruped
    for _ in range(100):
        action, _ = model.predict(obs, deterministic=True)
        assert action.shape == (4, 12) and np.isfinite(action).all() and np.abs(action).max() <= bound
        obs, _, _, infos = normalizer.step(action)
        assert not any(info["fall"] for info in infos)


@pytest.mark.parametrize(("algo", "env_id", "robot"), SHIPPED)
def test_rl_zoo_enjoy_loads_the_shipped_agent(algo: str, env_id: str, robot: str) -> None:
    script = shutil.which("rl_zoo3", path=str(Path(sys.executable).parent))
    command = [script] if script else [sys.executable, "-m", "sb3_huri.zoo"]
    command += ["enjoy", "--algo", algo, "--env", env_id, "-f", "trained_agents", "--no-render", "-n", "50"]
    result = subprocess.run(
        command, cwd=REPO, capture_output=True, text=True, timeout=300, env={**os.environ, "MUJOCO_GL": "egl"}
    )
    assert result.returncode == 0, result.stdout[-2000:] + result.stderr[-2000:]
    assert f"Loading trained_agents/{algo}/{env_id}_1/{env_id}.zip" in result.stdout


def test_readme_main_command_watches_every_shipped_agent_walk() -> None:
    """The README's main command (the block's last line, after its two set-up commands) runs each shipped
    agent at 0.5 m/s and reports it."""
    readme = (REPO / "README.md").read_text()
    block = readme.split("<!-- main-command -->", 1)[1].split("```bash\n", 1)[1].split("```", 1)[0]
    setup, watch = block.strip().splitlines()[:-1], block.strip().splitlines()[-1].split()
    assert len(setup) == 2 and "pip install" in setup[1], block
    assert watch[:2] == ["python", "examples/watch_zerith.py"], block
    result = subprocess.run(
        [sys.executable, *watch[1:], "--episodes", "1"], cwd=REPO, capture_output=True, text=True, timeout=300
    )
    assert result.returncode == 0, result.stdout[-2000:] + result.stderr[-2000:]
    for method, env_id, _ in SHIPPED:
        assert f"agent {REPO / 'trained_agents' / method / f'{env_id}_1'} ({method})" in result.stdout
    assert result.stdout.count("1/1 episodes without a fall") == len(SHIPPED), result.stdout
    speeds = [
        float(line.split("mean vx ")[1].split()[0])
        for line in result.stdout.splitlines()
        if "mean vx" in line
    ]
    assert len(speeds) == len(SHIPPED) and all(0.35 < v < 0.65 for v in speeds), result.stdout


def test_shipped_quadruped_walks_at_the_commanded_speed() -> None:
    """The quadruped's agent (trained on terrains, docs/go2like.md): 4 robots of `nominal` walk their 20 s at
    0.5 and 1 m/s, within 0.15 m/s of the command on average."""
    from sb3_huri.runner.evaluation import evaluate
    from sb3_huri.runner.folder import load_run

    model, normalizer = load_run(REPO / "trained_agents" / "huri" / "Go2Like-v0_1", "Go2Like-v0")
    for vx in (0.5, 1.0):
        result = evaluate(model, normalizer, "nominal", (vx, 0.0, 0.0), 4, 2000, workers=0, robot="go2like")
        assert result["survive"] == 1.0 and abs(result["vx"] - vx) < 0.15, (vx, result)


def test_sb3_ppo_loads_the_shipped_baseline_and_acts_as_huri_ppo_does() -> None:
    from stable_baselines3 import PPO

    path = REPO / "trained_agents" / "huri-baseline" / f"{ENV_ID}_1" / f"{ENV_ID}.zip"
    ppo, huri = PPO.load(path, device="cpu"), HuRiPPO.load(path, device="cpu")
    obs = zerith_gym.make_vec_env(4, seed=0, scenario="train").reset()
    noise = np.random.default_rng(0)
    obs = {key: value + noise.normal(size=value.shape) for key, value in obs.items()}
    expected = huri.predict(obs, deterministic=True)[0]
    np.testing.assert_array_equal(ppo.predict(obs, deterministic=True)[0], expected)
    observation = huri.policy.obs_to_tensor(obs)[0]
    np.testing.assert_array_equal(
        ppo.policy.predict_values(observation).detach(), huri.policy.predict_values(observation).detach()
    )


# ------------------------------------------------------------------------------------- gait measures
def _contacts(left_stance: np.ndarray, right_stance: np.ndarray) -> np.ndarray:
    return np.stack([left_stance, right_stance], axis=1)


def test_gait_measures_tell_walking_from_hopping_limping_and_standing() -> None:
    phase = (np.arange(350) % 35) / 35  # ten 0.7-s cycles at 50 Hz
    walk = _contacts(phase < 0.55, (phase + 0.5) % 1 < 0.55)
    rate, alternation, single = gait_measures(walk)
    assert rate == pytest.approx(20 / 7.0)  # two steps per cycle
    assert alternation == 1.0
    assert single == pytest.approx(np.mean(walk.sum(axis=1) == 1))
    hop = _contacts(phase < 0.55, phase < 0.55)
    assert gait_measures(hop)[1] == 0.0 and gait_measures(hop)[2] == 0.0
    limp = _contacts(phase < 0.55, np.ones(350, dtype=bool))
    assert gait_measures(limp)[0] == pytest.approx(10 / 7.0) and gait_measures(limp)[1] == 0.0
    stand = np.ones((350, 2), dtype=bool)
    assert gait_measures(stand) == (0.0, 0.0, 0.0)
    chatter = _contacts(np.arange(350) % 4 != 0, np.ones(350, dtype=bool))  # one-step losses of contact
    assert gait_measures(chatter)[0] == 0.0


def test_load_run_names_the_missing_model(tmp_path):
    from sb3_huri.runner.folder import load_run

    with pytest.raises(FileNotFoundError, match=r"Zerith1-v0\.zip not found"):
        load_run(tmp_path, "Zerith1-v0")


@pytest.mark.parametrize("method", AGENTS)
def test_shipped_agent_survives_the_papers_push_tests(method: str) -> None:
    """Both shipped agents were trained with the robust recipe and survive Table 1 (docs/training.md,
    "Shipped agents"): on the paper's sudden pushes at the centroid and the side impact, every one of 4 robots
    walks its 20 s at the 1 m/s command. A change to the env that breaks what they learned fails here."""
    from sb3_huri.runner.evaluation import evaluate
    from sb3_huri.runner.folder import load_run

    model, normalizer = load_run(REPO / "trained_agents" / method / f"{ENV_ID}_1", ENV_ID, normalized=True)
    for scenario in ("sudden-centroid", "side-impact"):
        result = evaluate(model, normalizer, scenario, None, episodes=4, seed=2000, workers=1)
        assert result["survive"] == 1.0, (scenario, result)
        assert result["vx"] > 0.6, (scenario, result)


def test_evaluate_agents_gives_each_case_of_each_agent_with_its_survival_interval() -> None:
    folders = [REPO / "trained_agents" / method / f"{ENV_ID}_1" for method in AGENTS]
    rows = agents.evaluate_agents(folders, ["nominal@0.5", "sudden-feet"], episodes=2, seed=1000)
    assert [(row.agent, row.case) for row in rows] == [
        (f"{method}/{ENV_ID}_1", case) for method in AGENTS for case in ("nominal@0.5", "sudden-feet")
    ]
    for row in rows:
        assert row.episodes == 2 and 0.0 <= row.low <= row.survive <= row.high <= 1.0
        assert row.high - row.low > 0.3  # two robots know a share only roughly


def test_compare_agents_pairs_the_robots_and_finds_no_difference_between_an_agent_and_itself() -> None:
    huri, ppo = (REPO / "trained_agents" / method / f"{ENV_ID}_1" for method in AGENTS)
    with pytest.raises(ValueError, match="unknown scenario 'sudden-head'"):  # before anything is evaluated
        agents.compare_agents(huri, ppo, ["sudden-centroid", "sudden-head"], episodes=3, seed=2000)
    (row,) = agents.compare_agents(huri, huri, ["sudden-centroid"], episodes=3, seed=2000)
    assert row["case"] == "sudden-centroid" and row["first"] == row["second"]  # deterministic, same robots
    assert row["difference"] == 0.0 and row["only_first"] == row["only_second"] == 0 and row["p_value"] == 1.0
    assert row["low"] < 0.0 < row["high"]
    assert row["vx_first"] == pytest.approx(row["vx_second"])
    assert "sudden-centroid" in agents.comparison_text([row]).splitlines()[1]


def test_compare_agents_averages_table1_per_robot() -> None:
    from scipy import stats

    rng = np.random.default_rng(3)
    first = {case: (rng.random(40) < 0.8, 0.8) for case in TABLE1_SCENARIOS}
    second = {case: (rng.random(40) < 0.6, 0.9) for case in TABLE1_SCENARIOS}
    rows = agents.compare(first, second)
    assert [row["case"] for row in rows] == [*TABLE1_SCENARIOS, "table1_mean"]
    per_robot = np.mean([first[c][0].astype(int) - second[c][0].astype(int) for c in first], axis=0)
    half_width = stats.t.ppf(0.975, 39) * per_robot.std(ddof=1) / np.sqrt(40)
    assert rows[-1]["difference"] == pytest.approx(per_robot.mean())
    assert rows[-1]["high"] - rows[-1]["difference"] == pytest.approx(half_width, rel=1e-4)  # t, 39 dof
    assert rows[-1]["first"] - rows[-1]["second"] == pytest.approx(per_robot.mean())
    for row, case in zip(rows, TABLE1_SCENARIOS, strict=False):
        disagree = first[case][0] != second[case][0]
        assert row["only_first"] + row["only_second"] == disagree.sum()
        expected = stats.binomtest(int((first[case][0] & disagree).sum()), int(disagree.sum())).pvalue
        assert row["p_value"] == pytest.approx(expected)


def test_copy_agent_keeps_what_acts_and_trains_and_leaves_the_rollout_state(tmp_path) -> None:
    """``copy_agent`` (how the quadruped's agent was shipped): the copy acts as the run does, trains on, and
    holds no robot's last observation."""
    from sb3_huri.runner.folder import copy_agent, load_run

    source = REPO / "trained_agents" / "huri-baseline" / f"{ENV_ID}_1"
    copy = copy_agent(source, ENV_ID, tmp_path / "agent")
    (model, normalizer), (copied, copied_normalizer) = load_run(source, ENV_ID), load_run(copy, ENV_ID)
    assert copied._last_obs is None and copied_normalizer.old_obs is None
    np.testing.assert_array_equal(copied_normalizer.obs_rms["policy"].mean, normalizer.obs_rms["policy"].mean)
    obs = zerith_gym.make_vec_env(4, seed=0, scenario="train").reset()
    np.testing.assert_array_equal(
        copied.predict(copied_normalizer.normalize_obs(obs), deterministic=True)[0],
        model.predict(normalizer.normalize_obs(obs), deterministic=True)[0],
    )
    for name in ("config.yml", "args.yml"):
        assert (copy / ENV_ID / name).read_text() == (source / ENV_ID / name).read_text()
    env = VecNormalize.load(str(copy / ENV_ID / "vecnormalize.pkl"), zerith_gym.make_vec_env(4, seed=0))
    trained = HuRiPPO.load(copy / f"{ENV_ID}.zip", env=env, device="cpu", n_steps=16, batch_size=32)
    trained.learn(64)
    assert trained.num_timesteps == 64


def test_watch_script_names_a_folder_without_an_agent_before_watching_any(tmp_path) -> None:
    shipped = str(REPO / "trained_agents" / "huri" / f"{ENV_ID}_1")
    command = [sys.executable, "examples/watch_zerith.py", shipped, str(tmp_path), "--episodes", "1"]
    result = subprocess.run(command, cwd=REPO, capture_output=True, text=True, timeout=120)
    assert result.returncode == 2 and "agent " not in result.stdout  # nothing watched
    assert f"{tmp_path} holds no agent" in result.stderr and "Zerith1-v0, Go2Like-v0" in result.stderr
