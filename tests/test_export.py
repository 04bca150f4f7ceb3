"""ONNX export of trained actors and the torch-free sim2sim runner.

The exported graphs must give SB3's deterministic actions along real episodes (normalization inside the
graph), carry what a controller needs in their metadata, and the runner must rebuild the env's own
observations from the robot's sensors, run where torch is missing, and refuse bad input clearly.
"""

from __future__ import annotations

import importlib.util
import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import gymnasium as gym
import numpy as np
import onnx
import onnxruntime
import pytest
import torch as th
from stable_baselines3 import PPO
from stable_baselines3.common.vec_env import DummyVecEnv, VecNormalize

import sb3_huri
import zerith_gym  # noqa: F401  (registers Zerith1-v0)
from sb3_huri import METHODS, HuRiPPO
from sb3_huri.export import FORMAT, actor_of, check_export, export_actor
from sb3_huri.export.__main__ import main
from sb3_huri.runner.folder import load_run
from zerith_gym.zerith1 import constants as robot
from zerith_gym.zerith1 import gait
from zerith_gym.zerith1.observations import POLICY_LAYOUT, POLICY_SIZE
from zerith_gym.zerith1.task import FALL_HEIGHT, FALL_TILT

REPO = Path(__file__).resolve().parents[1]
ENV_ID = "Zerith1-v0"
RUNS = {name: REPO / "trained_agents" / name / f"{ENV_ID}_1" for name in ("huri", "huri-baseline")}
RUNNER = REPO / "examples" / "deploy_onnx.py"


def load_runner():
    """Import examples/deploy_onnx.py as a module."""
    spec = importlib.util.spec_from_file_location("deploy_onnx", RUNNER)
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # dataclasses look their module up here
    spec.loader.exec_module(module)
    return module


def session(path: Path) -> onnxruntime.InferenceSession:
    return onnxruntime.InferenceSession(str(path), providers=["CPUExecutionProvider"])


def metadata(path: Path) -> dict:
    return {
        key: json.loads(value) for key, value in session(path).get_modelmeta().custom_metadata_map.items()
    }


@pytest.fixture(scope="module")
def exported(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """Both shipped runs exported through the command line."""
    folder = tmp_path_factory.mktemp("onnx")
    paths = {}
    for name, run in RUNS.items():
        paths[name] = folder / f"{name}.onnx"
        main([str(run), "--env", ENV_ID, "--output", str(paths[name])])
    return paths


@pytest.mark.parametrize(("name", "algorithm"), [("huri", HuRiPPO), ("huri-baseline", PPO)])
def test_onnx_actions_equal_sb3_predict_along_real_episodes(
    exported: dict[str, Path], name: str, algorithm: type
) -> None:
    """Training conditions (noise, randomization, pushes, falls and resets): 200 steps per run."""
    model = algorithm.load(RUNS[name] / f"{ENV_ID}.zip", device="cpu")  # the baseline by SB3's own PPO
    env = gym.make(ENV_ID)
    normalizer = VecNormalize.load(str(RUNS[name] / ENV_ID / "vecnormalize.pkl"), DummyVecEnv([lambda: env]))
    policy = session(exported[name])
    obs, _ = env.reset(seed=1)
    raw, expected = [], []
    for _ in range(200):
        action, _ = model.predict(normalizer.normalize_obs(obs), deterministic=True)
        (onnx_action,) = policy.run(["action"], {"obs": obs["policy"][None]})
        np.testing.assert_allclose(onnx_action[0], action, atol=1e-4, rtol=0)
        raw.append(obs["policy"])
        expected.append(action)
        obs, _, terminated, truncated, _ = env.step(action)
        if terminated or truncated:
            obs, _ = env.reset()
    (batch,) = policy.run(["action"], {"obs": np.array(raw)})  # the batch axis
    np.testing.assert_allclose(batch, np.array(expected), atol=1e-4, rtol=0)
    assert np.abs(batch).max() <= 1.0


@pytest.mark.parametrize("name", list(RUNS))
def test_the_file_carries_what_a_controller_needs(exported: dict[str, Path], name: str) -> None:
    proto = onnx.load(str(exported[name]))
    onnx.checker.check_model(proto, full_check=True)
    assert proto.opset_import[0].version == 17 and proto.ir_version == 8
    (graph_input,) = proto.graph.input
    dims = [d.dim_param or d.dim_value for d in graph_input.type.tensor_type.shape.dim]
    assert graph_input.name == "obs" and dims == ["batch", POLICY_SIZE]
    meta = metadata(exported[name])
    assert meta["format"] == FORMAT and meta["env_id"] == ENV_ID
    assert meta["package_version"] == sb3_huri.__version__
    assert meta["method"] == name and "variant" not in meta
    assert [(b["name"], b["size"]) for b in meta["observation_layout"]] == list(POLICY_LAYOUT)
    assert [b["start"] for b in meta["observation_layout"]] == list(
        np.cumsum([0] + [s for _, s in POLICY_LAYOUT])[:-1]
    )
    assert meta["joint_names"] == list(robot.JOINT_NAMES)
    np.testing.assert_array_equal(meta["action_scale"], robot.ACTION_SCALE)
    np.testing.assert_array_equal(meta["default_joint_pos"], robot.DEFAULT_JOINT_POS)
    np.testing.assert_array_equal(meta["kp"], robot.KP)
    assert meta["control_dt"] == robot.CONTROL_DT and meta["control_frequency_hz"] == 50
    assert meta["gait_steps"] * robot.CONTROL_DT == pytest.approx(gait.GAIT_PERIOD)
    stats = VecNormalize.load(
        str(RUNS[name] / ENV_ID / "vecnormalize.pkl"), DummyVecEnv([lambda: gym.make(ENV_ID)])
    )
    normalization = meta["observation_normalization"]
    assert normalization["in_graph"] and normalization["clip"] == stats.clip_obs
    assert normalization["epsilon"] == stats.epsilon
    mean = {t.name: onnx.numpy_helper.to_array(t) for t in proto.graph.initializer}["obs_mean"]
    np.testing.assert_allclose(mean, stats.obs_rms["policy"].mean, rtol=1e-6)


@pytest.mark.parametrize("method", sorted(METHODS))
def test_every_method_exports(tmp_path: Path, method: str) -> None:
    """Each method of the paper's comparison, untrained, with made-up normalization statistics."""
    venv = VecNormalize(DummyVecEnv([lambda: gym.make(ENV_ID)]))
    rng = np.random.default_rng(1)
    for rms in venv.obs_rms.values():
        rms.mean = rng.normal(size=rms.mean.shape)
        rms.var = rng.uniform(0.01, 4.0, size=rms.var.shape)
    model = HuRiPPO(
        "MultiInputPolicy",
        venv,
        method=method,
        n_steps=32,
        policy_kwargs=dict(net_arch=[32, 16]),
        device="cpu",
    )
    output = tmp_path / f"{method}.onnx"
    export_actor(model, venv, ENV_ID, output)
    assert metadata(output)["method"] == method
    assert check_export(output, model, venv) < 1e-5


def test_a_checkpoint_saved_with_a_variant_and_loaded_by_sb3s_ppo_exports_its_method(tmp_path: Path) -> None:
    """SB3's PPO loads the shipped baseline with what its zip holds, `variant="baseline"` (its name then)."""
    model = PPO.load(RUNS["huri-baseline"] / f"{ENV_ID}.zip", device="cpu")
    assert model.variant == "baseline"
    output = tmp_path / "baseline.onnx"
    export_actor(model, None, ENV_ID, output)
    assert metadata(output)["method"] == "huri-baseline"


def test_the_quadruped_exports_with_its_own_layout_joints_and_gains(tmp_path: Path) -> None:
    """`Go2Like-v0`: the metadata is the quadruped's (from its `RobotSpec` and `LocomotionTask`)."""
    from zerith_gym.go2like import constants as quadruped_robot
    from zerith_gym.go2like import task as legged_gym_task
    from zerith_gym.sb3.vec_env import make_vec_env

    venv = VecNormalize(make_vec_env(2, seed=0, robot="go2like", workers=0), norm_obs_keys=["policy"])
    model = HuRiPPO("MultiInputPolicy", venv, n_steps=16, policy_kwargs=dict(net_arch=[16]), device="cpu")
    output = tmp_path / "go2.onnx"
    export_actor(model, venv, "Go2Like-v0", output)
    data = metadata(output)
    assert data["robot"] == "Go2-like quadruped" and data["mjcf"].endswith("go2like.xml")
    assert data["joint_names"] == list(quadruped_robot.JOINT_NAMES) and data["kp"] == [20.0] * 12
    layout = {block["name"]: block for block in data["observation_layout"]}
    assert list(layout) == [name for name, _ in legged_gym_task.POLICY_LAYOUT]
    assert layout["height_samples"]["start"] == 48 and len(data["height_points"]) == 187
    assert data["command_ranges_training"]["vx"] == [-1.0, 1.0]  # quadruped-train, its default scenario
    assert check_export(output, model, venv) < 1e-5
    venv.close()


def test_plain_sb3_ppo_with_a_box_observation_and_tanh_layers(tmp_path: Path) -> None:
    """An SB3 PPO on the flat 46-d observation, saved in RL Zoo's layout with made-up statistics."""
    venv = VecNormalize(DummyVecEnv([lambda: gym.make(ENV_ID, obs_mode="policy")]))
    rng = np.random.default_rng(0)
    venv.obs_rms.mean = rng.normal(size=POLICY_SIZE)
    venv.obs_rms.var = rng.uniform(0.01, 4.0, size=POLICY_SIZE)
    model = PPO("MlpPolicy", venv, policy_kwargs=dict(net_arch=[32, 16]), seed=0, device="cpu")
    run = tmp_path / "ppo" / f"{ENV_ID}_1"
    (run / ENV_ID).mkdir(parents=True)
    model.save(run / f"{ENV_ID}.zip")
    venv.save(str(run / ENV_ID / "vecnormalize.pkl"))

    loaded, normalizer = load_run(run, ENV_ID, normalized=True)
    assert type(loaded) is PPO
    output = tmp_path / "plain.onnx"
    export_actor(loaded, normalizer, ENV_ID, output)
    assert actor_of(loaded.policy).key is None
    assert check_export(output, loaded, normalizer) < 1e-5
    assert metadata(output)["observation_key"] is None and metadata(output)["method"] is None


def test_squashed_gsde_actor_rescaled_to_the_action_bounds(tmp_path: Path) -> None:
    """gSDE with squash_output: the action is tanh of the mean, rescaled to Pendulum's [-2, 2]."""
    model = PPO(
        "MlpPolicy",
        "Pendulum-v1",
        use_sde=True,
        policy_kwargs=dict(squash_output=True, net_arch=[16], activation_fn=th.nn.SiLU),
        seed=0,
        device="cpu",
    )
    with th.no_grad():
        model.policy.action_net.weight.mul_(50.0)  # drive the mean into tanh's saturation
    output = tmp_path / "pendulum.onnx"
    export_actor(model, None, "Pendulum-v1", output)
    assert check_export(output, model, None) < 1e-5
    meta = metadata(output)
    assert meta["observation_normalization"] == {"in_graph": False} and "joint_names" not in meta
    (actions,) = session(output).run(
        ["action"], {"obs": np.random.default_rng(0).normal(size=(64, 3)).astype(np.float32) * 5}
    )
    assert np.abs(actions).max() > 1.5 and np.abs(actions).max() <= 2.0


def test_export_errors_say_what_is_wrong(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    def error_of(*argv: str) -> str:
        with pytest.raises(SystemExit) as exit_info:
            main([*argv, "--output", str(tmp_path / "out.onnx")])
        assert exit_info.value.code == 2
        return capsys.readouterr().err

    assert "run folder" in error_of(str(tmp_path / "nowhere"), "--env", ENV_ID)
    assert "unknown env id 'Zerith2-v0'" in error_of(str(RUNS["huri"]), "--env", "Zerith2-v0")
    assert "Zerith1-v0.zip not found" in error_of(str(tmp_path), "--env", ENV_ID)
    run = tmp_path / "huri" / f"{ENV_ID}_1"
    run.mkdir(parents=True)
    shutil.copy(RUNS["huri"] / f"{ENV_ID}.zip", run)
    message = error_of(str(run), "--env", ENV_ID)
    assert "vecnormalize.pkl not found" in message and "VecNormalize statistics" in message
    assert "--unnormalized" in message
    assert "normalized its observations" in error_of(str(RUNS["huri"]), "--unnormalized")
    assert not (tmp_path / "out.onnx").exists()


def test_runner_rebuilds_the_envs_observations_under_training_physics(exported: dict[str, Path]) -> None:
    """Same physics as training: the runner's observations from its sensors equal the env's, step by step."""
    runner = load_runner()
    assert (runner.FALL_HEIGHT, runner.FALL_TILT) == (FALL_HEIGHT, FALL_TILT)
    policy = runner.OnnxPolicy(exported["huri"])
    observations: list[np.ndarray] = []
    result = runner.run(
        policy,
        runner.default_mjcf(),
        runner.Physics.training(robot.PHYSICS_DT),
        (0.5, 0.0, 0.0),
        4.0,
        None,
        observations,
    )
    assert not result.fell and result.seconds == pytest.approx(4.0)
    env = gym.make(ENV_ID, scenario="nominal", command=(0.5, 0.0, 0.0))
    obs, _ = env.reset(seed=0)
    for step, runner_obs in enumerate(observations):
        np.testing.assert_allclose(runner_obs, obs["policy"], atol=1e-5, err_msg=f"step {step}")
        obs, *_ = env.step(policy(obs["policy"]))


BLOCKED = ("torch", "stable_baselines3", "sb3_huri", "zerith_gym", "gymnasium")


def run_without_torch(tmp_path: Path, *argv: str) -> subprocess.CompletedProcess:
    """The runner in a fresh interpreter where importing torch, SB3 or this repository's packages fails."""
    shims = tmp_path / "shims"
    shims.mkdir(exist_ok=True)
    for name in BLOCKED:
        (shims / f"{name}.py").write_text(f"raise ImportError('{name} is unavailable on this robot')\n")
    env = {**os.environ, "PYTHONPATH": str(shims), "MUJOCO_GL": "egl"}
    return subprocess.run(
        [sys.executable, str(RUNNER), *argv],
        cwd=tmp_path,
        env=env,
        capture_output=True,
        text=True,
        timeout=300,
    )


def test_runner_walks_without_torch_in_sim2sim_physics(exported: dict[str, Path], tmp_path: Path) -> None:
    """The MJCF and the ONNX file alone, 1 kHz physics and the CG solver; two runs of 3 s."""
    mjcf = tmp_path / "zerith1.xml"
    shutil.copy(REPO / "zerith_gym" / "zerith1" / "zerith1.xml", mjcf)
    argv = [str(exported["huri"]), "--seconds", "3", "--runs", "2", "--mjcf", str(mjcf), "--json"]
    result = run_without_torch(tmp_path, *argv)
    assert result.returncode == 0, result.stdout + result.stderr
    report = json.loads(result.stdout)
    assert report["falls"] == 0 and "1000 Hz physics, cg solver" in report["physics"]
    assert report["command"] == [0.5, 0.0, 0.0] and len(report["runs"]) == 2
    for run in report["runs"]:
        assert run["seconds"] == pytest.approx(3.0) and not run["fell"] and not run["diverged"]
        assert 0.1 < run["mean_velocity"][0] < 1.0 and run["lin_vel_error"] < 0.5
    assert report["runs"][0]["distance"] != report["runs"][1]["distance"]  # the second start differs


def test_runner_starts_are_the_default_stance_then_seeded_perturbations() -> None:
    runner = load_runner()
    first = runner.start_state(robot.DEFAULT_JOINT_POS, 0, seed=3)
    np.testing.assert_array_equal(first[0], robot.DEFAULT_JOINT_POS)
    assert first[1:] == (0.0, 0.0)
    joints, roll, pitch = runner.start_state(robot.DEFAULT_JOINT_POS, 1, seed=3)
    assert 0 < np.abs(joints - robot.DEFAULT_JOINT_POS).max() <= runner.START_JOINT_OFFSET
    assert 0 < max(abs(roll), abs(pitch)) <= runner.START_TILT
    np.testing.assert_array_equal(runner.start_state(robot.DEFAULT_JOINT_POS, 1, seed=3)[0], joints)
    assert not np.array_equal(runner.start_state(robot.DEFAULT_JOINT_POS, 1, seed=4)[0], joints)


def test_runner_refuses_files_it_cannot_use(tmp_path: Path, exported: dict[str, Path]) -> None:
    not_onnx = tmp_path / "policy.onnx"
    not_onnx.write_text("not a model")
    other = tmp_path / "pendulum.onnx"
    model = PPO("MlpPolicy", "Pendulum-v1", policy_kwargs=dict(net_arch=[8]), device="cpu")
    export_actor(model, None, "Pendulum-v1", other)
    foreign = tmp_path / "foreign.onnx"
    proto = onnx.load(str(exported["huri-baseline"]))
    del proto.metadata_props[:]
    onnx.save(proto, str(foreign))
    runner = load_runner()
    cases = {
        tmp_path / "missing.onnx": "not found",
        not_onnx: "not a readable ONNX model",
        foreign: "not an actor written by `python -m sb3_huri.export`",
        other: "without the robot metadata",
    }
    for path, message in cases.items():
        with pytest.raises(runner.DeployError, match=message.replace("(", r"\(")):
            runner.OnnxPolicy(path)
    with pytest.raises(runner.DeployError, match="must divide the control period"):
        runner.run(
            runner.OnnxPolicy(exported["huri-baseline"]),
            runner.default_mjcf(),
            runner.Physics(0.003),
            (0, 0, 0),
            1.0,
        )
    result = run_without_torch(tmp_path, str(not_onnx))
    assert result.returncode == 2 and "error: " in result.stderr and "Traceback" not in result.stderr


def test_runner_delay_applies_the_latest_targets_sent_at_least_that_long_before() -> None:
    """Zerith1-v0's convention (docs/zerith1.md): 25 ms at 5 ms physics applies the action of two control
    steps ago for the first physics step of a control step and the previous one for the other three."""
    physics = load_runner().Physics
    assert physics(0.005, delay=0.025).lags(4) == [2, 1, 1, 1]
    assert physics(0.001, delay=0.005).lags(20) == [1] * 5 + [0] * 15
    assert physics(0.001).lags(20) == [0] * 20


def test_runner_writes_a_video(exported: dict[str, Path], tmp_path: Path) -> None:
    runner = load_runner()
    video = tmp_path / "videos" / "walk.mp4"
    try:
        runner.run(
            runner.OnnxPolicy(exported["huri"]),
            runner.default_mjcf(),
            runner.Physics(),
            (0.5, 0, 0),
            0.5,
            video,
        )
    except runner.DeployError as error:
        if "cannot render" in str(error):
            pytest.skip(f"rendering unavailable: {error}")
        raise
    import imageio.v2 as imageio

    frames = imageio.mimread(str(video))
    assert len(frames) == 25 and frames[0].shape == (480, 640, 3)
