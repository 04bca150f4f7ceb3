"""RL Zoo integration, end to end: the real ``rl_zoo3`` CLI in subprocesses, run from a temporary folder.

Each CLI call pays a few seconds of imports (torch, RL Zoo), so one training run of ``Zerith1-v0`` is shared
by the ``enjoy``, ``record_video`` and output checks (module-scoped fixture).
"""

from __future__ import annotations

import os
import pickle
import shutil
import subprocess
import sys
from pathlib import Path

import gymnasium as gym
import pytest

pytest.importorskip("rl_zoo3", reason="RL Zoo is not installed (pip install -e '.[zoo]')")

import optuna
import yaml

import sb3_huri
from sb3_huri import HuRiPPO, UnnormalizedRewardWarning
from sb3_huri.zoo import METHODS, PRESETS_FILE, method_class
from sb3_huri.zoo.sampler import convert_huri_params, sample_huri_params

REPO = Path(__file__).resolve().parents[1]
CONF = str(REPO / "hyperparams" / "huri.yml")
HOOK_INSTALLED = any(type(finder).__name__ == "_RLZooFinder" for finder in sys.meta_path)
requires_hook = pytest.mark.skipif(
    not HOOK_INSTALLED, reason="the RL Zoo start-up hook is not installed (pip install -e . installs it)"
)


def rl_zoo3_command() -> list[str]:
    """This environment's ``rl_zoo3`` console script (``python -m rl_zoo3.cli`` if there is none)."""
    script = shutil.which("rl_zoo3", path=str(Path(sys.executable).parent))
    return [script] if script else [sys.executable, "-m", "rl_zoo3.cli"]


def run(command: list[str], cwd: Path, timeout: float = 300) -> subprocess.CompletedProcess[str]:
    """Run a command headless, fail the test with its output if it fails."""
    result = subprocess.run(
        command,
        cwd=cwd,
        env={**os.environ, "MUJOCO_GL": os.environ.get("MUJOCO_GL", "egl")},
        capture_output=True,
        text=True,
        timeout=timeout,
    )
    output = f"{result.stdout[-3000:]}\n{result.stderr[-3000:]}"
    assert result.returncode == 0, f"{' '.join(command)} failed:\n{output}"
    return result


def egl_rendering_works() -> bool:
    try:
        import mujoco

        model = mujoco.MjModel.from_xml_string("<mujoco><worldbody><geom size='1'/></worldbody></mujoco>")
        with mujoco.Renderer(model, 16, 16) as renderer:
            renderer.update_scene(mujoco.MjData(model))
            renderer.render()
    except Exception:
        return False
    return True


@pytest.fixture(scope="module")
def zerith_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A short Zerith1-v0 training with the documented command plus the flags users combine with it."""
    folder = tmp_path_factory.mktemp("zoo")
    # Without the hook (a checkout that was never installed), the wrapper runs the same command.
    zoo = rl_zoo3_command() if HOOK_INSTALLED else [sys.executable, "-m", "sb3_huri.zoo"]
    command = [
        *zoo,
        "train",
        "--algo", "huri",
        "--env", "Zerith1-v0",
        "-conf", CONF,
        "-n", "512",
        "--eval-freq", "128",
        "--eval-episodes", "1",
        "--seed", "7",
        "--tensorboard-log", "tb",
        "--num-threads", "1",
        "-params", "n_envs:2", "n_steps:64",
    ]  # fmt: skip
    run(command, folder)
    return folder


def test_train_writes_model_evaluations_and_tensorboard(zerith_run: Path) -> None:
    run_folder = zerith_run / "logs" / "huri" / "Zerith1-v0_1"
    assert (run_folder / "Zerith1-v0.zip").stat().st_size > 0
    assert (run_folder / "Zerith1-v0" / "vecnormalize.pkl").is_file()
    assert (run_folder / "evaluations.npz").is_file()  # --eval-freq
    # The robots ran in one batched env (zerith_gym.make_vec_env), which writes one monitor file, where
    # RL Zoo's DummyVecEnv of one env per robot would write one per robot.
    assert sorted(p.name for p in run_folder.glob("*.monitor.csv")) == ["0.monitor.csv"]
    args = yaml.load((run_folder / "Zerith1-v0" / "args.yml").read_text(), Loader=yaml.UnsafeLoader)
    assert args["seed"] == 7
    events = list((zerith_run / "tb" / "Zerith1-v0").rglob("events.out.tfevents.*"))  # --tensorboard-log
    assert events
    from tensorboard.backend.event_processing.event_accumulator import EventAccumulator

    tags = set().union(*(EventAccumulator(str(path)).Reload().Tags()["scalars"] for path in events))
    assert (
        "terms/lin_vel_error" in tags
    )  # the preset's `callback:` entry, zerith_gym.sb3.callbacks.RewardTermsLogger
    model = HuRiPPO.load(run_folder / "Zerith1-v0.zip", device="cpu")
    assert model.method == "huri"
    assert model.num_timesteps >= 512


@requires_hook
def test_enjoy_runs_the_trained_agent(zerith_run: Path) -> None:
    command = [*rl_zoo3_command(), "enjoy", "--algo", "huri", "--env", "Zerith1-v0", "-f", "logs"]
    result = run([*command, "-n", "60", "--no-render"], zerith_run)
    assert "Loading logs/huri/Zerith1-v0_1/Zerith1-v0.zip" in result.stdout


@requires_hook
def test_record_video_writes_a_video(zerith_run: Path) -> None:
    if not egl_rendering_works():
        pytest.skip("headless MuJoCo rendering (MUJOCO_GL=egl) is unavailable: install libegl1 and libgl1")
    command = [sys.executable, "-m", "rl_zoo3.record_video", "--algo", "huri", "--env", "Zerith1-v0"]
    run([*command, "-f", "logs", "-n", "20", "-o", "videos"], zerith_run)
    videos = list((zerith_run / "videos").glob("*.mp4"))
    assert videos, "no video written"
    assert videos[0].stat().st_size > 0


@requires_hook
def test_train_without_conf_uses_the_packaged_presets(tmp_path: Path) -> None:
    """``rl_zoo3 train --algo <method>`` with no ``-conf`` finds the presets shipped in the package."""
    command = [*rl_zoo3_command(), "train", "--algo", "huri-baseline", "--env", "Pendulum-v1", "-n", "256"]
    result = run([*command, "--eval-freq", "-1", "--num-threads", "1", "-params", "n_steps:64"], tmp_path)
    assert f"Loading hyperparameters from: {PRESETS_FILE}" in result.stdout
    model = HuRiPPO.load(tmp_path / "logs/huri-baseline/Pendulum-v1_1/Pendulum-v1.zip", device="cpu")
    assert model.method == "huri-baseline"


@requires_hook
def test_rl_zoo_trains_the_robust_preset(tmp_path: Path) -> None:
    """`rl_zoo3 train -conf hyperparams/huri_robust.yml`: its scenario, trust region and normalizer keys."""
    conf = str(REPO / "hyperparams" / "huri_robust.yml")
    command = [*rl_zoo3_command(), "train", "--algo", "huri", "--env", "Zerith1-v0", "-conf", conf,
               "-n", "256", "--eval-freq", "-1", "--seed", "0", "-f", "logs", "--num-threads", "1",
               "-params", "n_envs:2", "n_steps:64"]  # fmt: skip
    run(command, tmp_path)
    folder = tmp_path / "logs" / "huri" / "Zerith1-v0_1"
    model = HuRiPPO.load(folder / "Zerith1-v0.zip")
    assert model.desired_kl == 0.007 and model.critic_learning_rate == pytest.approx(3e-4)
    assert [g["name"] for g in model.policy.optimizer.param_groups] == ["actor", "critic"]
    assert "scenario: robust" in (folder / "Zerith1-v0" / "config.yml").read_text()
    with open(folder / "Zerith1-v0" / "vecnormalize.pkl", "rb") as file:
        assert pickle.load(file).norm_obs_keys == ["policy"]


def test_rl_zoo_trains_the_quadruped_preset_on_the_batched_env(tmp_path: Path) -> None:
    """`rl_zoo3 train --algo huri-baseline --env Go2Like-v0`: the packaged preset, one batched env."""
    command = [*rl_zoo3_command(), "train", "--algo", "huri-baseline", "--env", "Go2Like-v0", "-conf", CONF,
               "-n", "256", "--eval-freq", "-1", "--seed", "0", "-f", "logs", "--num-threads", "1",
               "-params", "n_envs:2", "n_steps:64"]  # fmt: skip
    run(command, tmp_path)
    folder = tmp_path / "logs" / "huri-baseline" / "Go2Like-v0_1"
    model = HuRiPPO.load(folder / "Go2Like-v0.zip")
    assert model.observation_space["policy"].shape == (235,) and model.num_timesteps == 256
    assert len(list(folder.glob("*.monitor.csv"))) == 1  # one batched env, not one env per robot


@requires_hook
def test_rl_zoo_trains_on_terrains_with_the_terrain_curriculum(tmp_path: Path) -> None:
    """`rl_zoo3 train -conf hyperparams/huri_terrain.yml`: the terrain scenario and the level's log."""
    conf = str(REPO / "hyperparams" / "huri_terrain.yml")
    command = [*rl_zoo3_command(), "train", "--algo", "huri", "--env", "Zerith1-v0", "-conf", conf,
               "-n", "256", "--eval-freq", "-1", "--seed", "0", "-f", "logs", "--num-threads", "1",
               "-params", "n_envs:2", "n_steps:64"]  # fmt: skip
    result = run(command, tmp_path)
    folder = tmp_path / "logs" / "huri" / "Zerith1-v0_1"
    assert "scenario: terrain" in (folder / "Zerith1-v0" / "config.yml").read_text()
    assert "terrain/" in result.stdout and "max_level_share" in result.stdout  # TerrainCurriculum's log


def test_wrapper_works_without_the_hook(tmp_path: Path) -> None:
    """``python -m sb3_huri.zoo`` registers HuRi by itself: run it with the start-up hook switched off."""
    without_hook = (
        "import runpy, sys;"
        "sys.meta_path[:] = [f for f in sys.meta_path if type(f).__name__ != '_RLZooFinder'];"
        "import rl_zoo3;"
        "assert 'huri' not in rl_zoo3.ALGOS, 'the start-up hook is still active';"
        "sys.argv[0] = 'sb3_huri.zoo';"
        "runpy.run_module('sb3_huri.zoo', run_name='__main__', alter_sys=True)"
    )
    arguments = ["train", "--algo", "huri-cvar0.5", "--env", "Pendulum-v1", "-conf", CONF, "-n", "256"]
    run(
        [sys.executable, "-c", without_hook, *arguments, "--eval-freq", "-1", "-params", "n_steps:64"],
        tmp_path,
    )
    model = HuRiPPO.load(tmp_path / "logs/huri-cvar0.5/Pendulum-v1_1/Pendulum-v1.zip", device="cpu")
    assert model.method == "huri-cvar0.5"


@requires_hook
def test_hook_imports_nothing_heavy_at_interpreter_start(tmp_path: Path) -> None:
    watched = "{'torch', 'numpy', 'rl_zoo3', 'sb3_huri', '_sb3_huri_zoo_hook'}"
    result = run([sys.executable, "-c", f"import sys; print(sorted(set(sys.modules) & {watched}))"], tmp_path)
    assert result.stdout.strip() == "['_sb3_huri_zoo_hook']"


@requires_hook
def test_hook_never_breaks_the_import_of_rl_zoo3(tmp_path: Path) -> None:
    """With sb3_huri unimportable, importing rl_zoo3 still works, and the hook says what failed."""
    probe = "import sys; sys.modules['sb3_huri'] = None; import rl_zoo3; print('huri' in rl_zoo3.ALGOS)"
    result = run([sys.executable, "-c", probe], tmp_path)
    assert result.stdout.strip() == "False"
    assert "warning: sb3_huri.zoo.register_algorithms() failed when rl_zoo3 was imported" in result.stderr


@requires_hook
def test_importing_rl_zoo3_registers_every_method_and_the_env() -> None:
    import rl_zoo3
    from rl_zoo3.hyperparams_opt import HYPERPARAMS_SAMPLER

    for method in METHODS:
        assert rl_zoo3.ALGOS[method] is method_class(method)
        assert HYPERPARAMS_SAMPLER[method] is sample_huri_params
    assert "Zerith1-v0" in gym.registry


def test_the_methods_are_the_presets_names_in_order() -> None:
    assert METHODS == (
        "huri-baseline", "huri-neutral", "huri-cvar0.5", "huri-no-rnd", "huri-no-iqr", "huri",
        "huri-percentile", "huri-cvar",
    )  # fmt: skip
    assert tuple(sb3_huri.METHODS) == METHODS


@pytest.mark.parametrize("method", sorted(METHODS))
def test_method_class_fixes_the_method(method: str) -> None:
    model = method_class(method)("MlpPolicy", "Pendulum-v1", n_steps=8, device="cpu")
    assert isinstance(model, HuRiPPO)
    assert model.method == method


def test_the_default_method_is_the_printed_band_and_the_percentile_band_is_its_own_class() -> None:
    """`HuRiPPO()` is HuRi with the band as printed, the RL Zoo algorithm `huri` that takes any `method`;
    `huri-percentile` (runs, agents, --algo) keeps the scale-free band, a class of its own."""
    assert method_class("huri") is HuRiPPO
    default = HuRiPPO("MlpPolicy", "Pendulum-v1", n_steps=8, device="cpu")
    assert default.method == "huri" and default.risk_model.iqr_band == "absolute"
    adaptive = method_class("huri-percentile")("MlpPolicy", "Pendulum-v1", n_steps=8, device="cpu")
    assert type(adaptive) is not HuRiPPO and adaptive.risk_model.iqr_band == "percentile"
    explicit = HuRiPPO("MlpPolicy", "Pendulum-v1", method="huri-percentile", n_steps=8, device="cpu")
    assert explicit.risk_model.iqr_band == "percentile"


def test_method_class_rejects_a_conflicting_method_and_an_unknown_one() -> None:
    with pytest.raises(
        ValueError, match=r"method='huri-no-rnd' conflicts with the algorithm huri-cvar0.5.*--algo huri$"
    ):
        method_class("huri-cvar0.5")("MlpPolicy", "Pendulum-v1", method="huri-no-rnd", device="cpu")
    with pytest.raises(ValueError, match=r"unknown method 'cvar0.5': expected one of \['huri-baseline'"):
        method_class("cvar0.5")


def test_sampled_hyperparameters_build_a_model() -> None:
    trial = optuna.trial.FixedTrial(
        {
            "n_steps_pow": 5,
            "n_minibatches": 2,
            "n_epochs": 4,
            "learning_rate": 1e-3,
            "one_minus_gamma": 0.01,
            "one_minus_gae_lambda": 0.05,
            "ent_coef": 1e-3,
            "clip_range": 0.2,
            "max_grad_norm": 0.5,
            "expectation_coef": 0.1,
            "iqr_low": 0.2,
            "iqr_width": 0.5,
        }
    )
    hyperparams = sample_huri_params(trial, n_actions=1, n_envs=1, additional_args={})
    assert hyperparams["n_steps"] == 32
    assert hyperparams["gamma"] == pytest.approx(0.99)
    assert hyperparams["gae_lambda"] == pytest.approx(0.95)
    assert hyperparams["iqr_thresholds"] == pytest.approx((0.2, 0.7))
    assert convert_huri_params(trial.params) == hyperparams
    model = HuRiPPO("MlpPolicy", "Pendulum-v1", device="cpu", **hyperparams)
    assert model.batch_size == 16  # 32 steps split into 2 minibatches
    with pytest.warns(UnnormalizedRewardWarning, match=r"\(0.2, 0.7\)"):  # the sampled band, unnormalized
        model.learn(64)


@pytest.mark.slow
@requires_hook
def test_optimize_runs_trials_with_the_huri_sampler(tmp_path: Path) -> None:
    command = [*rl_zoo3_command(), "train", "--algo", "huri", "--env", "Pendulum-v1", "-conf", CONF]
    options = [
        "-optimize",
        "--n-trials",
        "2",
        "--n-startup-trials",
        "2",
        "-n",
        "1024",
        "--n-evaluations",
        "1",
    ]
    result = run([*command, *options, "--eval-episodes", "1", "--no-optim-plots"], tmp_path)
    assert "Number of finished trials:  2" in result.stdout
    assert "iqr_thresholds" in result.stdout
