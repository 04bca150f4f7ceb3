"""Export the actor of a trained run to ONNX, with its observation normalization inside the graph.

    python -m sb3_huri.export trained_agents/huri/Zerith1-v0_1 --env Zerith1-v0 --output policy.onnx

The ONNX file maps the raw observation the actor reads (for Zerith1-v0 the 46-value ``policy`` entry, a
batch axis allowed) to the deterministic action exactly as Stable-Baselines3's ``predict`` returns it:
the run's ``VecNormalize`` statistics (mean, variance, epsilon, clip) normalize the input, the actor's MLP
gives the mean action, and the action is clipped to the action space. Everything a controller needs to
run it without torch or SB3 (observation layout, joint order, action scale, default joint positions,
control period, gait clock) is written into the file's metadata; ``examples/deploy_onnx.py`` uses it.

The graph is written node by node with ``onnx.helper`` from the policy's weights rather than traced by
``torch.onnx``: an SB3 actor is a stack of ``Linear`` layers and element-wise activations, which map one to
one onto ONNX's ``Gemm`` and activation operators, so the graph is exact and the export does not depend on
torch's exporters (the TorchScript one is deprecated, the ``torch.export`` one needs ``onnxscript``).
The file uses opset 17 and IR version 8, which ONNX Runtime has read since its version 1.11.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import torch as th
from gymnasium import spaces
from stable_baselines3.common.distributions import (
    DiagGaussianDistribution,
    StateDependentNoiseDistribution,
)
from stable_baselines3.common.policies import ActorCriticPolicy
from stable_baselines3.common.torch_layers import FlattenExtractor, MlpExtractor
from torch import nn

from sb3_huri.huri.policies import AsymmetricMlpExtractor, PolicyCriticExtractor
from sb3_huri.version import __version__
from sb3_huri.zoo.runs import load_run

FORMAT = "sb3_huri.actor/1"
"""Value of the ``format`` metadata entry: tells a runner the file is an actor written by this module."""
OPSET = 17
IR_VERSION = 8
INPUT_NAME = "obs"
OUTPUT_NAME = "action"

_ZERITH_BLOCK_NOTES = {
    "base_roll_pitch": "pelvis roll = atan2(u_y, u_z) and pitch = asin(-u_x) (rad), where u is the world's "
    "up axis expressed in the pelvis (IMU) frame, i.e. minus the normalized gravity the IMU measures",
    "base_angular_velocity": "gyro at the pelvis, pelvis frame (rad/s)",
    "clock_sin_cos": "sin and cos of 2 pi phase, phase = (k mod gait_steps) / gait_steps where k counts the "
    "control steps since the controller started (k = 0 for the first observation)",
    "command": "commanded vx, vy (m/s) and yaw rate (rad/s), in the base's heading frame",
    "joint_position_offset": "joint positions minus default_joint_pos, in joint_names order (rad)",
    "joint_velocity": "joint velocities, in joint_names order (rad/s)",
    "last_action": "the action this graph returned at the previous control step (zeros at the start)",
}
"""How each block of Zerith1-v0's policy observation is measured on the robot."""


@dataclass(frozen=True)
class Normalization:
    """``VecNormalize``'s observation normalization: clip((obs - mean) / sqrt(var + epsilon), -clip, clip)."""

    mean: np.ndarray
    var: np.ndarray
    epsilon: float
    clip: float


@dataclass(frozen=True)
class Actor:
    """What the deterministic actor of an SB3 ``ActorCriticPolicy`` computes, in export-ready pieces.

    ``key`` is the ``Dict`` observation entry the actor reads (``None`` for a flat ``Box`` observation),
    ``layers`` the modules from that entry to the mean action, ``squash`` whether the mean goes through
    tanh and is rescaled to the action bounds (SB3's ``squash_output``) instead of being clipped to them.
    """

    key: str | None
    input_size: int
    layers: tuple[nn.Module, ...]
    squash: bool
    low: np.ndarray
    high: np.ndarray


def actor_of(policy: Any) -> Actor:
    """Decompose the actor of `policy`; ``ValueError`` saying why when it cannot be exported.

    Exportable: an ``ActorCriticPolicy`` with a ``Box`` action space and a Gaussian (or gSDE) action
    distribution whose actor reads one flat observation: a 1-D ``Box`` through ``FlattenExtractor``, or
    the ``"policy"`` entry of a ``Dict`` through HuRi's asymmetric extractor.
    """
    if not isinstance(policy, ActorCriticPolicy):
        raise ValueError(f"only ActorCriticPolicy actors can be exported, got {type(policy).__name__}")
    action_space = policy.action_space
    if not isinstance(action_space, spaces.Box) or len(action_space.shape) != 1:
        raise ValueError(f"only 1-D Box action spaces can be exported, got {action_space}")
    if not isinstance(policy.action_dist, DiagGaussianDistribution | StateDependentNoiseDistribution):
        raise ValueError(
            f"only Gaussian action distributions can be exported, got {type(policy.action_dist).__name__}"
        )
    extractor, mlp = policy.pi_features_extractor, policy.mlp_extractor
    obs_space = policy.observation_space
    if isinstance(extractor, FlattenExtractor) and isinstance(obs_space, spaces.Box):
        if len(obs_space.shape) != 1:
            raise ValueError(f"only 1-D Box observations can be exported, got shape {obs_space.shape}")
        key, size = None, int(obs_space.shape[0])
        reads_all = isinstance(mlp, MlpExtractor) or (
            isinstance(mlp, AsymmetricMlpExtractor) and mlp.reads_all_features
        )
    elif isinstance(extractor, PolicyCriticExtractor) and isinstance(mlp, AsymmetricMlpExtractor):
        key, size = extractor.keys[0], extractor.actor_features_dim
        reads_all = not mlp.reads_all_features and mlp.actor_dim == size
        if reads_all and len(obs_space[key].shape) != 1:
            raise ValueError(f"the actor's observation {key!r} must be 1-D, got shape {obs_space[key].shape}")
    else:
        raise ValueError(
            f"the actor reads its observation through {type(extractor).__name__} and "
            f"{type(mlp).__name__}: only actors of one flat observation (a 1-D Box, or the 'policy' entry of "
            "a Dict with HuRiPolicy) can be exported"
        )
    if not reads_all:
        raise ValueError("the actor reads more than one observation entry: it cannot take one flat input")
    return Actor(
        key=key,
        input_size=size,
        layers=(*_flat_modules(mlp.policy_net), policy.action_net),
        squash=bool(policy.squash_output),
        low=np.asarray(action_space.low, dtype=np.float32),
        high=np.asarray(action_space.high, dtype=np.float32),
    )


def _flat_modules(module: nn.Module) -> list[nn.Module]:
    """The leaf modules of nested ``nn.Sequential`` containers, in order."""
    if isinstance(module, nn.Sequential):
        return [leaf for child in module for leaf in _flat_modules(child)]
    return [module]


def normalization_of(normalizer: Any, key: str | None, size: int) -> Normalization | None:
    """The normalization a ``VecNormalize`` applies to the actor's input; None if it applies none."""
    if normalizer is None or not normalizer.norm_obs:
        return None
    if key is None:
        rms = normalizer.obs_rms
        if isinstance(rms, dict):
            raise ValueError("the normalizer holds statistics of a Dict observation, the actor reads a Box")
    else:
        if not isinstance(normalizer.obs_rms, dict):
            raise ValueError(f"the actor reads the Dict entry {key!r}, the normalizer a Box observation")
        if key not in (normalizer.norm_obs_keys or []):
            return None
        rms = normalizer.obs_rms[key]
    mean, var = np.asarray(rms.mean, dtype=np.float64), np.asarray(rms.var, dtype=np.float64)
    if mean.shape != (size,) or var.shape != (size,):
        raise ValueError(f"normalization statistics of shape {mean.shape} for an actor input of size {size}")
    return Normalization(mean, var, float(normalizer.epsilon), float(normalizer.clip_obs))


class _GraphBuilder:
    """Collects ONNX nodes and constant tensors; each ``op`` call returns the name of its output."""

    def __init__(self) -> None:
        from onnx import helper, numpy_helper

        self._helper, self._numpy_helper = helper, numpy_helper
        self.nodes: list[Any] = []
        self.initializers: list[Any] = []

    def constant(self, name: str, value: Any) -> str:
        """Add a float32 constant tensor called `name`."""
        array = np.asarray(value, dtype=np.float32)
        self.initializers.append(self._numpy_helper.from_array(array, name))
        return name

    def op(self, op_type: str, *inputs: str, output: str | None = None, **attributes: Any) -> str:
        """Add one node; its output is called `output`, or after the node's position in the graph."""
        output = output or f"{op_type.lower()}_{len(self.nodes)}"
        self.nodes.append(self._helper.make_node(op_type, list(inputs), [output], name=output, **attributes))
        return output


def _activation(graph: _GraphBuilder, module: nn.Module, x: str) -> str:
    """The ONNX nodes of one element-wise activation module."""
    if isinstance(module, nn.ELU):
        return graph.op("Elu", x, alpha=float(module.alpha))
    if isinstance(module, nn.LeakyReLU):
        return graph.op("LeakyRelu", x, alpha=float(module.negative_slope))
    if isinstance(module, nn.SiLU):
        return graph.op("Mul", x, graph.op("Sigmoid", x))
    simple = {nn.ReLU: "Relu", nn.Tanh: "Tanh", nn.Sigmoid: "Sigmoid", nn.Softsign: "Softsign"}
    for kind, op_type in simple.items():
        if isinstance(module, kind):
            return graph.op(op_type, x)
    if isinstance(module, nn.Identity):
        return x
    supported = "Linear, ELU, LeakyReLU, ReLU, Tanh, Sigmoid, SiLU, Softsign, Identity"
    raise ValueError(f"cannot export the actor's layer {module!r}: supported layers are {supported}")


def actor_graph(actor: Actor, normalization: Normalization | None) -> Any:
    """The ONNX graph (``onnx.GraphProto``): raw observation (batch, n) -> action (batch, m), float32."""
    from onnx import TensorProto, helper

    graph = _GraphBuilder()
    x = INPUT_NAME
    if normalization is not None:
        # VecNormalize computes in float64; in float32 the graph matches it to about 1e-7 relative.
        std = np.sqrt(normalization.var + normalization.epsilon)
        x = graph.op("Sub", x, graph.constant("obs_mean", normalization.mean))
        x = graph.op("Div", x, graph.constant("obs_std", std))
        x = graph.op(
            "Clip",
            x,
            graph.constant("obs_clip_low", -normalization.clip),
            graph.constant("obs_clip_high", normalization.clip),
        )
    for index, layer in enumerate(actor.layers):
        if isinstance(layer, nn.Linear):
            weight = graph.constant(f"layer{index}_weight", layer.weight.detach().cpu().numpy())
            bias = (
                []
                if layer.bias is None
                else [graph.constant(f"layer{index}_bias", layer.bias.detach().cpu().numpy())]
            )
            x = graph.op("Gemm", x, weight, *bias, transB=1)
        else:
            x = _activation(graph, layer, x)
    low, high = actor.low, actor.high
    if actor.squash:  # SB3's unscale_action of the tanh-squashed mean: low + (a + 1) (high - low) / 2
        x = graph.op("Add", graph.op("Tanh", x), graph.constant("one", 1.0))
        x = graph.op("Mul", x, graph.constant("half_range", (high - low) / 2))
        graph.op("Add", x, graph.constant("action_low", low), output=OUTPUT_NAME)
    elif (low == low[0]).all() and (high == high[0]).all():
        graph.op(
            "Clip",
            x,
            graph.constant("action_low", low[0]),
            graph.constant("action_high", high[0]),
            output=OUTPUT_NAME,
        )
    else:
        x = graph.op("Max", x, graph.constant("action_low", low))
        graph.op("Min", x, graph.constant("action_high", high), output=OUTPUT_NAME)
    return helper.make_graph(
        graph.nodes,
        "actor",
        [helper.make_tensor_value_info(INPUT_NAME, TensorProto.FLOAT, ["batch", actor.input_size])],
        [helper.make_tensor_value_info(OUTPUT_NAME, TensorProto.FLOAT, ["batch", len(low)])],
        graph.initializers,
    )


def _training_scenario(run: Path, env_id: str) -> str:
    """The scenario a run folder's `args.yml` names (RL Zoo's layout), `train` if it names none."""
    import yaml

    args_file = run / env_id / "args.yml"
    try:
        saved = yaml.safe_load(args_file.read_text()) if args_file.is_file() else None
    except yaml.YAMLError:  # RL Zoo's own args.yml is an OrderedDict with a Python tag
        saved = None
    env_kwargs = (saved or {}).get("env_kwargs") if isinstance(saved, dict) else None
    return str((env_kwargs or {}).get("scenario", "train"))


def deployment_metadata(env_id: str, input_size: int, training_scenario: str = "train") -> dict[str, Any]:
    """What a controller needs to build the observation and apply the action, for `env_id`'s robot
    trained in `training_scenario` (whose command ranges it reports).

    Empty for environments other than this package's robots (the graph itself is still complete).
    """
    import gymnasium as gym

    entry_point = str(gym.spec(env_id).entry_point)
    if not entry_point.startswith("zerith_gym"):
        return {}
    from zerith_gym import gait, robot
    from zerith_gym.observations import POLICY_LAYOUT, POLICY_SIZE, layout_slices
    from zerith_gym.scenarios import SCENARIOS

    if input_size != POLICY_SIZE:
        raise ValueError(
            f"{env_id}'s policy observation has {POLICY_SIZE} values, the actor reads {input_size}"
        )
    slices = layout_slices(POLICY_LAYOUT)
    commands = SCENARIOS[training_scenario].command_ranges
    return {
        "robot": "Zerith-1",
        "mjcf": "zerith_gym/assets/zerith1.xml",
        "observation_layout": [
            {
                "name": name,
                "start": slices[name].start,
                "size": size,
                "description": _ZERITH_BLOCK_NOTES.get(name, "see docs/zerith1.md"),
            }
            for name, size in POLICY_LAYOUT
        ],
        "joint_names": list(robot.JOINT_NAMES),
        "default_joint_pos": robot.DEFAULT_JOINT_POS.tolist(),
        "action_scale": robot.ACTION_SCALE.tolist(),
        "joint_target": "default_joint_pos + action_scale * action (rad), per joint in joint_names order, "
        "tracked by joint PD controllers (kp, kd) with torque limits",
        "kp": robot.KP.tolist(),
        "kd": robot.KD.tolist(),
        "torque_limit": robot.TORQUE_LIMIT.tolist(),
        "control_dt": robot.CONTROL_DT,
        "control_frequency_hz": round(1.0 / robot.CONTROL_DT),
        "physics_dt_training": robot.PHYSICS_DT,
        "gait_period": gait.GAIT_PERIOD,
        "gait_steps": round(gait.GAIT_PERIOD / robot.CONTROL_DT),
        "gait_foot_phase_offsets": gait.FOOT_PHASE_OFFSETS.tolist(),
        "command_ranges_training": {
            "vx": list(commands.vx),
            "vy": list(commands.vy),
            "yaw_rate": list(commands.yaw_rate),
        },
    }


def export_actor(
    model: Any,
    normalizer: Any,
    env_id: str,
    output: str | os.PathLike,
    source: str | None = None,
    training_scenario: str = "train",
) -> Any:
    """Write the deterministic actor of `model`, with `normalizer`'s observation normalization, to `output`.

    `normalizer` is the run's ``VecNormalize`` (or None for a run without one); `source` names the run in
    the metadata, `training_scenario` the scenario it was trained in. Returns the ``onnx.ModelProto`` written.
    """
    import onnx
    from onnx import helper

    actor = actor_of(model.policy)
    normalization = normalization_of(normalizer, actor.key, actor.input_size)
    metadata: dict[str, Any] = {
        "format": FORMAT,
        "env_id": env_id,
        "package": "sb3-huri",
        "package_version": __version__,
        "algorithm": type(model).__name__,
        "variant": getattr(model, "variant", None),
        "source": source,
        "input": INPUT_NAME,
        "output": OUTPUT_NAME,
        "observation_key": actor.key,
        "observation_size": actor.input_size,
        "action_size": len(actor.low),
        "action_low": actor.low.tolist(),
        "action_high": actor.high.tolist(),
        "action_postprocess": "tanh, rescaled to [action_low, action_high]" if actor.squash else "clip",
        "observation_normalization": (
            {"in_graph": False}
            if normalization is None
            else {
                "in_graph": True,
                "formula": "clip((obs - mean) / sqrt(var + epsilon), -clip, clip)",
                "epsilon": normalization.epsilon,
                "clip": normalization.clip,
            }
        ),
        **deployment_metadata(env_id, actor.input_size, training_scenario),
    }
    proto = helper.make_model(
        actor_graph(actor, normalization),
        opset_imports=[helper.make_opsetid("", OPSET)],
        ir_version=IR_VERSION,
        producer_name="sb3_huri.export",
        producer_version=__version__,
        doc_string=f"Deterministic actor for {env_id}: raw observation -> action. Metadata values are JSON.",
    )
    helper.set_model_props(proto, {key: json.dumps(value) for key, value in metadata.items()})
    onnx.checker.check_model(proto, full_check=True)
    onnx.save(proto, os.fspath(output))
    return proto


def check_export(
    path: str | os.PathLike, model: Any, normalizer: Any, samples: int = 256, seed: int = 0
) -> float:
    """Largest difference between ONNX Runtime's actions and ``model.predict(..., deterministic=True)``.

    The observations are drawn around the normalization statistics (a few of them far out, to reach the
    observation clip), the other entries of a ``Dict`` observation are zeros (the actor does not read them).
    """
    import onnxruntime

    actor = actor_of(model.policy)
    normalization = normalization_of(normalizer, actor.key, actor.input_size)
    rng = np.random.default_rng(seed)
    mean = np.zeros(actor.input_size) if normalization is None else normalization.mean
    std = np.ones(actor.input_size) if normalization is None else np.sqrt(normalization.var)
    spread = np.where(np.arange(samples) < samples // 8, 20.0, 2.0)[:, None]
    raw = (mean + spread * std * rng.standard_normal((samples, actor.input_size))).astype(np.float32)
    if actor.key is None:
        obs: Any = raw
    else:
        obs = {
            key: np.zeros((samples, *space.shape), np.float32)
            for key, space in model.observation_space.items()
        }
        obs[actor.key] = raw
    if normalizer is not None:
        obs = normalizer.normalize_obs(obs)
    expected, _ = model.predict(obs, deterministic=True)
    session = onnxruntime.InferenceSession(os.fspath(path), providers=["CPUExecutionProvider"])
    (actions,) = session.run([OUTPUT_NAME], {INPUT_NAME: raw})
    return float(np.abs(actions - expected).max())


def main(argv: Sequence[str] | None = None) -> None:
    """Command line: export a run folder's actor, then check it against SB3 when ONNX Runtime is installed."""
    parser = argparse.ArgumentParser(
        prog="python -m sb3_huri.export",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument(
        "run", type=Path, help="run folder in RL Zoo's layout (<env>.zip, <env>/vecnormalize.pkl)"
    )
    parser.add_argument("--env", default="Zerith1-v0", help="environment id of the run (default: Zerith1-v0)")
    parser.add_argument("--output", "-o", type=Path, required=True, help="the ONNX file to write")
    parser.add_argument(
        "--unnormalized",
        action="store_true",
        help="the run was trained without VecNormalize (no statistics file)",
    )
    args = parser.parse_args(argv)
    th.set_num_threads(1)
    try:
        import onnx  # noqa: F401
    except ImportError:
        parser.exit(2, "error: the onnx package is needed to export: pip install 'sb3-huri[deploy]'\n")
    try:
        model, normalizer = load_run(args.run, args.env, normalized=not args.unnormalized)
        run = args.run.resolve()
        export_actor(
            model,
            normalizer,
            args.env,
            args.output,
            f"{run.parent.name}/{run.name}",
            _training_scenario(run, args.env),
        )
    except (FileNotFoundError, ValueError) as error:
        parser.exit(2, f"error: {error}\n")
    actor = actor_of(model.policy)
    entry = f"the '{actor.key}' entry, " if actor.key else ""
    normalized = "normalized in the graph" if normalizer is not None else "not normalized"
    size = args.output.stat().st_size / 1024
    print(
        f"wrote {args.output} ({size:.0f} KiB): {INPUT_NAME} (batch, {actor.input_size}) raw observation "
        f"({entry}{normalized}) -> {OUTPUT_NAME} (batch, {len(actor.low)})"
    )
    try:
        import onnxruntime  # noqa: F401
    except ImportError:
        print("onnxruntime is not installed: the export was not checked against SB3's predict")
        return
    difference = check_export(args.output, model, normalizer)
    print(f"checked with ONNX Runtime: largest difference to SB3's predict {difference:.1e}")
    if difference > 1e-4:
        parser.exit(1, "error: the exported actor does not match the model\n")


if __name__ == "__main__":
    main(sys.argv[1:])
