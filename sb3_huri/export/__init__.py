"""Export the actor of a trained run to ONNX, with its observation normalization inside the graph.

    python -m sb3_huri.export trained_agents/huri/Zerith1-v0_1 --env Zerith1-v0 --output policy.onnx

The ONNX file maps the raw observation the actor reads (for Zerith1-v0 the 46-value ``policy`` entry, a
batch axis allowed) to the deterministic action exactly as Stable-Baselines3's ``predict`` returns it:
the run's ``VecNormalize`` statistics (mean, variance, epsilon, clip) normalize the input, the actor's MLP
gives the mean action, and the action is clipped to the action space. Everything a controller needs to
run it without torch or SB3 (observation layout, joint order, action scale, default joint positions,
control period, gait clock) is written into the file's metadata; ``examples/deploy_onnx.py`` uses it.

Modules: ``graph`` (the actor's layers and normalization as ONNX nodes), ``metadata`` (what a controller
needs, from the robot's declarations), ``onnx_file`` (writing and checking the file; opset 17 and IR
version 8, which ONNX Runtime has read since its version 1.11) and the command line (``__main__``).
"""

from __future__ import annotations

from sb3_huri.export.graph import (
    INPUT_NAME,
    OUTPUT_NAME,
    Actor,
    Normalization,
    actor_graph,
    actor_of,
    normalization_of,
)
from sb3_huri.export.metadata import deployment_metadata
from sb3_huri.export.onnx_file import FORMAT, IR_VERSION, OPSET, check_export, export_actor

__all__ = [
    "FORMAT",
    "INPUT_NAME",
    "IR_VERSION",
    "OPSET",
    "OUTPUT_NAME",
    "Actor",
    "Normalization",
    "actor_graph",
    "actor_of",
    "check_export",
    "deployment_metadata",
    "export_actor",
    "normalization_of",
]
