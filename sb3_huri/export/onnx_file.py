"""Writing an actor's ONNX file with its metadata, and checking it against SB3's ``predict``."""

from __future__ import annotations

import json
import os
from typing import Any

import numpy as np

from sb3_huri.export.graph import INPUT_NAME, OUTPUT_NAME, actor_graph, actor_of, normalization_of
from sb3_huri.export.metadata import deployment_metadata
from sb3_huri.huri.methods import method_of_saved
from sb3_huri.version import __version__

FORMAT = "sb3_huri.actor/1"
"""Value of the ``format`` metadata entry: tells a runner the file is an actor written by this package."""
OPSET = 17
IR_VERSION = 8


def export_actor(
    model: Any,
    normalizer: Any,
    env_id: str,
    output: str | os.PathLike,
    source: str | None = None,
    training_scenario: str | None = None,
) -> Any:
    """Write the deterministic actor of `model`, with `normalizer`'s observation normalization, to `output`.

    `normalizer` is the run's ``VecNormalize`` (or None for a run without one); `source` names the run in
    the metadata, `training_scenario` the scenario it was trained in (None: the robot's default).
    Returns the ``onnx.ModelProto`` written.
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
        "method": method_of_saved(vars(model)),
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
