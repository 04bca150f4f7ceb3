"""An SB3 actor as an ONNX graph: its layers read from the policy, its normalization, written node by node.

The graph is written with ``onnx.helper`` from the policy's weights rather than traced by ``torch.onnx``: an
SB3 actor is a stack of ``Linear`` layers and element-wise activations, which map one to one onto ONNX's
``Gemm`` and activation operators, so the graph is exact and the export does not depend on torch's
exporters (the TorchScript one is deprecated, the ``torch.export`` one needs ``onnxscript``).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from gymnasium import spaces
from stable_baselines3.common.distributions import (
    DiagGaussianDistribution,
    StateDependentNoiseDistribution,
)
from stable_baselines3.common.policies import ActorCriticPolicy
from stable_baselines3.common.torch_layers import FlattenExtractor, MlpExtractor
from torch import nn

from sb3_huri.huri.policies import AsymmetricMlpExtractor, PolicyCriticExtractor

INPUT_NAME = "obs"
OUTPUT_NAME = "action"


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
