"""Sim2sim: drive the Zerith-1 MJCF with plain MuJoCo at 50 Hz from an exported ONNX actor alone.

    python -m sb3_huri.export trained_agents/huri/Zerith1-v0_1 --output huri.onnx
    python examples/deploy_onnx.py huri.onnx                        # 20 s at 0.5 m/s, 1 kHz physics, CG
    python examples/deploy_onnx.py huri.onnx --command 0.3 0 0.3 --seconds 10
    python examples/deploy_onnx.py huri.onnx --physics-dt 0.002 --solver pgs --integrator euler
    python examples/deploy_onnx.py huri.onnx --training-physics       # the physics the policy was trained on
    MUJOCO_GL=egl python examples/deploy_onnx.py huri.onnx --video huri.mp4

The controller needs numpy, mujoco and onnxruntime only (no torch, no Stable-Baselines3, no zerith_gym
code): everything about the robot comes from the ONNX file's metadata (observation layout, joint order,
default joint positions, action scale, control period, gait clock), written by `python -m sb3_huri.export`.
At each 50 Hz tick it reads what the robot's own sensors give (the IMU's orientation and gyro, the joint
encoders' positions and velocities), builds the 46-value observation, runs the ONNX actor and sends joint
position targets to the robot's PD-controlled actuators.

The simulator is the MJCF (`zerith_gym/zerith1/zerith1.xml`, found without importing the package; `--mjcf`
for another copy) with physics settings other than training's by default: a 1 kHz physics step (training
used 5 ms), the CG solver (training: Newton) and elliptic friction cones (training: pyramidal). The robot
starts in the default stance, standing, with the command held for the whole run. The run reports whether
the robot fell (pelvis below 0.45 m or tilted beyond 0.8 rad, the env's criterion) and how well it
tracked the commanded velocity, measured at the pelvis with the simulator's ground truth.
"""

from __future__ import annotations

import argparse
import dataclasses
import importlib.util
import json
import math
import sys
from collections import deque
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import mujoco
import numpy as np

FORMAT = "sb3_huri.actor/1"
"""The `format` metadata entry of actors written by `python -m sb3_huri.export`."""
FALL_HEIGHT = 0.45
"""A fall: the pelvis is lower than this (m) above the ground ..."""
FALL_TILT = 0.8
"""... or tilted more than this (rad) from upright (Zerith1-v0's criterion)."""
GROUND_CLEARANCE = 0.002
"""Gap (m) left under the lowest sole corner when the robot is placed at the start."""
SOLVERS = {
    "newton": mujoco.mjtSolver.mjSOL_NEWTON,
    "cg": mujoco.mjtSolver.mjSOL_CG,
    "pgs": mujoco.mjtSolver.mjSOL_PGS,
}
INTEGRATORS = {
    "euler": mujoco.mjtIntegrator.mjINT_EULER,
    "implicit": mujoco.mjtIntegrator.mjINT_IMPLICIT,
    "implicitfast": mujoco.mjtIntegrator.mjINT_IMPLICITFAST,
    "rk4": mujoco.mjtIntegrator.mjINT_RK4,
}
CONES = {"pyramidal": mujoco.mjtCone.mjCONE_PYRAMIDAL, "elliptic": mujoco.mjtCone.mjCONE_ELLIPTIC}
REQUIRED_METADATA = (
    "observation_layout",
    "joint_names",
    "default_joint_pos",
    "action_scale",
    "control_dt",
    "gait_steps",
    "input",
    "output",
)


class DeployError(Exception):
    """A problem with the inputs of a deployment run (the ONNX file, the MJCF, the settings)."""


# ------------------------------------------------------------------------------------------- the controller
class OnnxPolicy:
    """An actor written by `python -m sb3_huri.export`: its ONNX Runtime session and its metadata."""

    def __init__(self, path: str | Path) -> None:
        try:
            import onnxruntime
        except ImportError as error:
            raise DeployError(
                "onnxruntime is needed: pip install onnxruntime (or 'sb3-huri[deploy]')"
            ) from error

        path = Path(path)
        if not path.is_file():
            raise DeployError(f"{path} not found")
        options = onnxruntime.SessionOptions()
        options.intra_op_num_threads = 1  # a small MLP: one thread is fastest, as on a robot's computer
        options.inter_op_num_threads = 1
        try:
            self.session = onnxruntime.InferenceSession(
                str(path), options, providers=["CPUExecutionProvider"]
            )
        except Exception as error:  # onnxruntime raises its own exception types for unreadable files
            raise DeployError(f"{path} is not a readable ONNX model: {error}") from error
        raw = self.session.get_modelmeta().custom_metadata_map
        try:
            self.metadata: dict[str, Any] = {key: json.loads(value) for key, value in raw.items()}
        except json.JSONDecodeError as error:
            raise DeployError(
                f"{path} has metadata that is not JSON: not written by sb3_huri.export"
            ) from error
        if self.metadata.get("format") != FORMAT:
            raise DeployError(
                f"{path} is not an actor written by `python -m sb3_huri.export` (its 'format' metadata is "
                f"{self.metadata.get('format')!r}, expected {FORMAT!r})"
            )
        missing = [key for key in REQUIRED_METADATA if key not in self.metadata]
        if missing:
            raise DeployError(
                f"{path} was exported for {self.metadata.get('env_id')!r} without the robot metadata this "
                f"runner needs (missing: {', '.join(missing)}): export a Zerith1-v0 run"
            )
        self.input, self.output = self.metadata["input"], self.metadata["output"]

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        """The action (m,) for one observation (n,)."""
        (action,) = self.session.run([self.output], {self.input: obs[None].astype(np.float32)})
        return action[0]


@dataclass
class Readings:
    """What the robot's on-board sensors give at a control tick."""

    up: np.ndarray  # (3,) the world's up axis in the pelvis (IMU) frame: the IMU's gravity estimate
    gyro: np.ndarray  # (3,) pelvis angular velocity, pelvis frame (rad/s)
    joint_pos: np.ndarray  # (12,) joint encoders, in the policy's joint order (rad)
    joint_vel: np.ndarray  # (12,) rad/s


class Controller:
    """The 50 Hz loop of the robot's computer: sensors -> observation -> ONNX actor -> joint targets.

    `command` is (vx, vy, yaw rate); it may be changed between ticks. The gait clock counts the ticks
    since the controller started, as the policy's training did from each episode's start.
    """

    BLOCKS = (
        "base_roll_pitch",
        "base_angular_velocity",
        "clock_sin_cos",
        "command",
        "joint_position_offset",
        "joint_velocity",
        "last_action",
    )
    """The observation blocks this controller can build (Zerith1-v0's policy observation)."""

    def __init__(self, policy: OnnxPolicy, command: tuple[float, float, float] | np.ndarray) -> None:
        meta = policy.metadata
        self.policy = policy
        self.command = np.asarray(command, dtype=float)
        self.default_joint_pos = np.asarray(meta["default_joint_pos"], dtype=float)
        self.action_scale = np.asarray(meta["action_scale"], dtype=float)
        self.gait_steps = int(meta["gait_steps"])
        self.layout = [(block["name"], int(block["size"])) for block in meta["observation_layout"]]
        unknown = [name for name, _ in self.layout if name not in self.BLOCKS]
        if unknown:
            raise DeployError(f"the actor's observation has blocks this controller cannot build: {unknown}")
        self.step = 0
        self.last_action = np.zeros(len(self.default_joint_pos))

    def observation(self, readings: Readings) -> np.ndarray:
        """The actor's observation at the current tick, in the layout of the ONNX file's metadata."""
        up = readings.up
        phase = 2.0 * math.pi * ((self.step % self.gait_steps) / self.gait_steps)
        blocks = {
            "base_roll_pitch": [math.atan2(up[1], up[2]), math.asin(min(max(-up[0], -1.0), 1.0))],
            "base_angular_velocity": readings.gyro,
            "clock_sin_cos": [math.sin(phase), math.cos(phase)],
            "command": self.command,
            "joint_position_offset": readings.joint_pos - self.default_joint_pos,
            "joint_velocity": readings.joint_vel,
            "last_action": self.last_action,
        }
        parts = [np.asarray(blocks[name], dtype=float) for name, _ in self.layout]
        for (name, size), part in zip(self.layout, parts, strict=True):
            if part.shape != (size,):
                raise DeployError(
                    f"observation block {name!r} has {part.size} values, the actor expects {size}"
                )
        return np.concatenate(parts).astype(np.float32)

    def tick(self, readings: Readings) -> tuple[np.ndarray, np.ndarray]:
        """One control step: the observation and the joint position targets (rad) to send."""
        obs = self.observation(readings)
        self.last_action = self.policy(obs).astype(float)
        self.step += 1
        return obs, self.default_joint_pos + self.action_scale * self.last_action


# -------------------------------------------------------------------------------------------- the simulator
@dataclass(frozen=True)
class Physics:
    """MuJoCo settings of the simulated robot; the defaults differ from training's on purpose."""

    timestep: float = 0.001
    solver: str = "cg"
    integrator: str = "implicitfast"
    cone: str = "elliptic"
    delay: float = 0.0
    """Actuation delay (s): new joint targets reach the actuators this long after the observation."""

    @staticmethod
    def training(model_timestep: float) -> Physics:
        """The settings Zerith1-v0 trains with: the MJCF's 5 ms step, Newton, Euler, pyramidal."""
        return Physics(model_timestep, "newton", "euler", "pyramidal")

    def describe(self) -> str:
        text = (
            f"{1 / self.timestep:.0f} Hz physics, {self.solver} solver, {self.integrator}, {self.cone} cones"
        )
        return text + (f", {self.delay * 1000:g} ms delay" if self.delay else "")

    def substeps(self, control_dt: float) -> int:
        """Physics steps per control period; DeployError unless the physics step divides the period."""
        count = round(control_dt / self.timestep)
        if count < 1 or abs(count * self.timestep - control_dt) > 1e-9:
            raise DeployError(
                f"the physics step ({self.timestep} s) must divide the control period ({control_dt} s)"
            )
        return count

    def lags(self, substeps: int) -> list[int]:
        """For each physics step of a control step, how many control steps old the targets it applies are.

        Physics step j of control step k applies the latest targets sent at least `delay` before it.
        """
        delay_steps = round(self.delay / self.timestep)
        return [max(0, -(-(delay_steps - j) // substeps)) for j in range(substeps)]


def default_mjcf() -> Path:
    """The Zerith-1 MJCF of the installed zerith_gym package, located without importing the package."""
    spec = importlib.util.find_spec("zerith_gym")
    if spec is None or not spec.submodule_search_locations:
        raise DeployError("zerith_gym is not installed: pass the robot's MJCF with --mjcf")
    return Path(next(iter(spec.submodule_search_locations))) / "zerith1" / "zerith1.xml"


class SimulatedRobot:
    """The MJCF in MuJoCo: sensors read by name, actuators addressed by the policy's joint names."""

    def __init__(self, mjcf: Path, joint_names: list[str], physics: Physics) -> None:
        if not mjcf.is_file():
            raise DeployError(f"MJCF {mjcf} not found")
        self.model = mujoco.MjModel.from_xml_path(str(mjcf))
        self.model.opt.timestep = physics.timestep
        self.model.opt.solver = SOLVERS[physics.solver]
        self.model.opt.integrator = INTEGRATORS[physics.integrator]
        self.model.opt.cone = CONES[physics.cone]
        self.data = mujoco.MjData(self.model)
        model = self.model
        actuator_of_joint = {
            mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_JOINT, model.actuator_trnid[a, 0]): a
            for a in range(model.nu)
        }
        missing = [name for name in joint_names if name not in actuator_of_joint]
        if missing:
            raise DeployError(f"the MJCF has no actuated joints called {missing}: is it the policy's robot?")
        self.actuators = np.array([actuator_of_joint[name] for name in joint_names])
        self.qpos_address = np.array([model.joint(name).qposadr[0] for name in joint_names])
        self._sensor = {}
        for name in ("base_up", "base_angvel", "base_pos", "base_linvel"):
            self._sensor[name] = self._sensor_slice(name)
        self._joint_pos = np.array([self._sensor_slice(f"{name}_pos").start for name in joint_names])
        self._joint_vel = np.array([self._sensor_slice(f"{name}_vel").start for name in joint_names])
        self.feet = [model.geom(name).id for name in ("left_foot", "right_foot")]

    def _sensor_slice(self, name: str) -> slice:
        sensor_id = mujoco.mj_name2id(self.model, mujoco.mjtObj.mjOBJ_SENSOR, name)
        if sensor_id < 0:
            raise DeployError(f"the MJCF has no sensor called {name!r}")
        start = int(self.model.sensor_adr[sensor_id])
        return slice(start, start + int(self.model.sensor_dim[sensor_id]))

    def reset(self, joint_pos: np.ndarray, roll: float = 0.0, pitch: float = 0.0) -> None:
        """Stand the robot in `joint_pos`, its pelvis tilted by `roll` and `pitch` (rad), at rest, its
        lowest sole corner just above the ground."""
        model, data = self.model, self.data
        mujoco.mj_resetData(model, data)
        data.qpos[:3] = 0.0
        (cr, cp), (sr, sp) = np.cos([roll / 2, pitch / 2]), np.sin([roll / 2, pitch / 2])
        data.qpos[3:7] = (cp * cr, cp * sr, sp * cr, -sp * sr)  # pitch about y after roll about x
        data.qpos[self.qpos_address] = joint_pos
        data.ctrl[self.actuators] = joint_pos
        mujoco.mj_kinematics(model, data)
        corners = np.array([(x, y, -1.0) for x in (-1.0, 1.0) for y in (-1.0, 1.0)])
        lowest = min(
            (
                data.geom_xpos[g, 2] + data.geom_xmat[g].reshape(3, 3)[2] @ (corners * model.geom_size[g]).T
            ).min()
            for g in self.feet
        )
        data.qpos[2] -= lowest - GROUND_CLEARANCE
        mujoco.mj_forward(model, data)

    def readings(self) -> Readings:
        """The on-board sensors (as of the start of the last physics step, as a sensor bus delivers them)."""
        s = self.data.sensordata
        return Readings(
            up=s[self._sensor["base_up"]].copy(),
            gyro=s[self._sensor["base_angvel"]].copy(),
            joint_pos=s[self._joint_pos].copy(),
            joint_vel=s[self._joint_vel].copy(),
        )

    def ground_truth(self) -> tuple[np.ndarray, np.ndarray]:
        """Pelvis position (world) and linear velocity (pelvis frame): for the evaluation, not the policy."""
        s = self.data.sensordata
        return s[self._sensor["base_pos"]].copy(), s[self._sensor["base_linvel"]].copy()

    def step(self, segments: list[tuple[np.ndarray, int]]) -> bool:
        """Physics steps holding joint targets, as (targets, physics steps) runs; False if it diverged."""
        for targets, count in segments:
            self.data.ctrl[self.actuators] = targets
            mujoco.mj_step(self.model, self.data, nstep=count)
        return bool(np.isfinite(self.data.qvel).all())


# ------------------------------------------------------------------------------------------------- the run
START_JOINT_OFFSET = 0.1
"""Runs after the first start from joint positions offset by up to this much (rad, uniform) ..."""
START_TILT = 0.05
"""... and a pelvis roll and pitch of up to this much (rad, uniform)."""


def start_state(default_joint_pos: np.ndarray, run_index: int, seed: int) -> tuple[np.ndarray, float, float]:
    """Initial joint positions, roll and pitch of run `run_index`: the default stance, upright, for run 0;
    a random perturbation of it (drawn from `seed` and the index) for the others."""
    if run_index == 0:
        return default_joint_pos, 0.0, 0.0
    rng = np.random.default_rng([seed, run_index])
    offsets = rng.uniform(-START_JOINT_OFFSET, START_JOINT_OFFSET, len(default_joint_pos))
    roll, pitch = rng.uniform(-START_TILT, START_TILT, 2)
    return default_joint_pos + offsets, float(roll), float(pitch)


@dataclass
class Result:
    """What a run measured; velocities are means over the control steps walked."""

    seconds: float
    fell: bool
    fall_time: float | None
    diverged: bool
    command: list[float]
    mean_velocity: list[float]  # vx, vy (pelvis frame, m/s), yaw rate (rad/s)
    lin_vel_error: float  # mean |v_xy - v_xy_cmd| (m/s)
    ang_vel_error: float  # mean |yaw rate - commanded| (rad/s)
    distance: float  # pelvis displacement in the ground plane (m)
    physics: str


def run(
    policy: OnnxPolicy,
    mjcf: Path,
    physics: Physics,
    command: tuple[float, float, float],
    seconds: float,
    video: Path | None = None,
    observations: list[np.ndarray] | None = None,
    run_index: int = 0,
    seed: int = 0,
) -> Result:
    """Run the controller on the simulated robot for `seconds`, or until it falls.

    The robot starts from `start_state(run_index, seed)`. With `observations` (a list) every observation
    the controller built is appended to it.
    """
    meta = policy.metadata
    control_dt = float(meta["control_dt"])
    substeps = physics.substeps(control_dt)
    robot = SimulatedRobot(mjcf, list(meta["joint_names"]), physics)
    controller = Controller(policy, np.asarray(command, dtype=float))
    robot.reset(*start_state(controller.default_joint_pos, run_index, seed))
    start, _ = robot.ground_truth()
    lags = physics.lags(substeps)
    runs = [(lag, lags.count(lag)) for lag in sorted(set(lags), reverse=True)]  # lags never increase
    sent = deque([controller.default_joint_pos] * (max(lags) + 1), maxlen=max(lags) + 1)  # newest last
    frames, renderer, camera = [], None, -1
    if video is not None:
        imageio = video_module()  # before the run: a missing package should not cost a simulation
        try:
            renderer = mujoco.Renderer(robot.model, height=480, width=640)
        except Exception as error:  # no OpenGL context: MuJoCo's error names the back-end that failed
            raise DeployError(f"cannot render ({error}); on a headless machine set MUJOCO_GL=egl") from error
        if mujoco.mj_name2id(robot.model, mujoco.mjtObj.mjOBJ_CAMERA, "track") >= 0:
            camera = "track"  # Zerith-1's camera that follows the robot

    cos_fall_tilt = math.cos(FALL_TILT)
    velocities, fell, diverged, steps = [], False, False, round(seconds / control_dt)
    for _ in range(steps):
        obs, targets = controller.tick(robot.readings())
        if observations is not None:
            observations.append(obs)
        sent.append(targets)
        if not robot.step([(sent[-1 - lag], count) for lag, count in runs]):
            diverged = True
            break
        position, linvel = robot.ground_truth()
        readings = robot.readings()
        velocities.append([linvel[0], linvel[1], readings.gyro[2]])
        if renderer is not None:
            renderer.update_scene(robot.data, camera=camera)
            frames.append(renderer.render())
        if position[2] < FALL_HEIGHT or readings.up[2] < cos_fall_tilt:
            fell = True
            break
    if renderer is not None:
        renderer.close()
        video.parent.mkdir(parents=True, exist_ok=True)
        imageio.mimwrite(str(video), frames, fps=round(1.0 / control_dt), macro_block_size=1)

    v = np.asarray(velocities).reshape(-1, 3)
    cmd = np.asarray(command, dtype=float)
    end, _ = robot.ground_truth()
    return Result(
        seconds=len(v) * control_dt,
        fell=fell,
        fall_time=len(v) * control_dt if fell else None,
        diverged=diverged,
        command=cmd.tolist(),
        mean_velocity=v.mean(axis=0).tolist() if len(v) else [0.0, 0.0, 0.0],
        lin_vel_error=float(np.hypot(v[:, 0] - cmd[0], v[:, 1] - cmd[1]).mean()) if len(v) else 0.0,
        ang_vel_error=float(np.abs(v[:, 2] - cmd[2]).mean()) if len(v) else 0.0,
        distance=float(np.hypot(*(end[:2] - start[:2]))),
        physics=physics.describe(),
    )


def video_module() -> Any:
    """imageio, which writes the video (with its ffmpeg plugin, imageio-ffmpeg)."""
    try:
        import imageio.v2 as imageio
        import imageio_ffmpeg  # noqa: F401
    except ImportError as error:
        raise DeployError(
            "--video needs imageio and imageio-ffmpeg: pip install imageio imageio-ffmpeg"
        ) from error
    return imageio


def summary(result: Result) -> str:
    """One line about one run."""
    vx, vy, wz = result.mean_velocity
    outcome = (
        f"fell at {result.fall_time:.2f} s" if result.fell else "diverged" if result.diverged else "no fall"
    )
    return (
        f"{result.seconds:5.2f} s, {outcome}; mean vx {vx:.2f} m/s, vy {vy:.2f} m/s, "
        f"yaw rate {wz:.2f} rad/s; mean |v_xy error| {result.lin_vel_error:.3f} m/s, "
        f"|yaw rate error| {result.ang_vel_error:.3f} rad/s; {result.distance:.2f} m from the start"
    )


def main(argv: list[str] | None = None) -> None:
    """Command line: exit status 1 if the robot fell or the simulation diverged in a run, 2 on bad input."""
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("policy", type=Path, help="an ONNX actor written by python -m sb3_huri.export")
    parser.add_argument("--seconds", type=float, default=20.0, help="how long each run lasts (default 20)")
    parser.add_argument(
        "--command",
        type=float,
        nargs=3,
        default=(0.5, 0.0, 0.0),
        metavar=("VX", "VY", "WZ"),
        help="velocity command: m/s forward and left, rad/s yaw rate (default 0.5 0 0)",
    )
    parser.add_argument(
        "--runs",
        type=int,
        default=1,
        help="number of runs: the first from the default stance, the others from perturbed ones (default 1)",
    )
    parser.add_argument("--seed", type=int, default=0, help="seed of the perturbed starts (default 0)")
    parser.add_argument(
        "--video", type=Path, default=None, help="write an mp4 of the first run (headless: MUJOCO_GL=egl)"
    )
    parser.add_argument("--mjcf", type=Path, default=None, help="the robot's MJCF (default: zerith_gym's)")
    physics = parser.add_argument_group("physics (defaults differ from training's: 5 ms, newton, pyramidal)")
    physics.add_argument(
        "--physics-dt", type=float, default=Physics.timestep, help="physics step (s), default 0.001"
    )
    physics.add_argument("--solver", choices=list(SOLVERS), default=Physics.solver)
    physics.add_argument("--integrator", choices=list(INTEGRATORS), default=Physics.integrator)
    physics.add_argument("--cone", choices=list(CONES), default=Physics.cone)
    physics.add_argument(
        "--delay",
        type=float,
        default=0.0,
        help="actuation delay (ms) from observation to actuators (default 0)",
    )
    physics.add_argument(
        "--training-physics", action="store_true", help="use training's physics settings instead of the above"
    )
    parser.add_argument("--json", action="store_true", help="print the results as one JSON object")
    args = parser.parse_args(argv)
    results: list[Result] = []
    try:
        if args.seconds <= 0 or args.runs < 1 or args.delay < 0:
            raise DeployError("--seconds and --runs must be positive, --delay must not be negative")
        policy = OnnxPolicy(args.policy)
        mjcf = args.mjcf or default_mjcf()
        if not mjcf.is_file():
            raise DeployError(f"MJCF {mjcf} not found")
        if args.training_physics:
            settings = Physics.training(mujoco.MjModel.from_xml_path(str(mjcf)).opt.timestep)
        else:
            settings = Physics(args.physics_dt, args.solver, args.integrator, args.cone)
        settings = dataclasses.replace(settings, delay=args.delay / 1000)
        settings.substeps(float(policy.metadata["control_dt"]))
        command = tuple(args.command)
        if not args.json:
            meta = policy.metadata
            method = meta.get("method", meta.get("variant"))  # earlier exports name it `variant`
            agent = f"{meta.get('algorithm')} ({method}) for {meta.get('env_id')}"
            print(f"{args.policy}: {agent}; {settings.describe()}; command {command}")
        for index in range(args.runs):
            video = args.video if index == 0 else None
            results.append(run(policy, mjcf, settings, command, args.seconds, video, None, index, args.seed))
            if not args.json:
                print(f"  run {index}: {summary(results[-1])}")
    except DeployError as error:
        parser.exit(2, f"error: {error}\n")
    failures = sum(result.fell or result.diverged for result in results)
    if args.json:
        report = {"physics": settings.describe(), "command": list(command), "falls": failures}
        print(json.dumps({**report, "runs": [dataclasses.asdict(result) for result in results]}))
    elif args.runs > 1:
        mean = np.mean([[*r.mean_velocity, r.lin_vel_error, r.ang_vel_error] for r in results], axis=0)
        print(
            f"  {failures}/{args.runs} runs fell or diverged; over the runs: mean vx {mean[0]:.2f} m/s, "
            f"vy {mean[1]:.2f} m/s, yaw rate {mean[2]:.2f} rad/s; |v_xy error| {mean[3]:.3f} m/s, "
            f"|yaw rate error| {mean[4]:.3f} rad/s"
        )
    if args.video and not args.json:
        print(f"  video of run 0: {args.video}")
    sys.exit(1 if failures else 0)


if __name__ == "__main__":
    main()
