"""A symmetry loss on the actor: act on a mirrored observation as on the original, mirrored.

An env whose task is left-right symmetric (Zerith1-v0: `zerith_gym.symmetry`) gives two signed permutations,
`policy_mirror` of the actor's observation and `action_mirror` of the action (objects with `index` and
`sign` arrays: ``mirrored[..., i] = sign[i] * x[..., index[i]]``). The loss is the mean over the minibatch
of ``|mu(mirror(o)) - action_mirror(mu(o))|^2``, with ``mu`` the actor's action mean: a symmetric policy
scores 0. The actor sees normalized observations (`VecNormalize`), so the mirror is carried into normalized
units: ``normalize(mirror(x)) = scale * x_normalized[index] + shift`` (clipping aside).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, NamedTuple

import numpy as np
import torch as th


class NormalizedMirror(NamedTuple):
    """A signed permutation carried into a normalizer's units: ``x -> scale * x[..., index] + shift``."""

    index: th.Tensor
    scale: th.Tensor
    shift: th.Tensor

    def __call__(self, x: th.Tensor) -> th.Tensor:
        return x[..., self.index] * self.scale + self.shift

    @staticmethod
    def build(
        mirror: Any,
        mean: np.ndarray | None = None,
        std: np.ndarray | None = None,
        device: th.device | str = "cpu",
    ) -> NormalizedMirror:
        """The map of normalized values ``(x - mean) / std`` that `mirror` (``index``, ``sign``) makes of
        the raw ones; without `mean` and `std`, `mirror` itself."""
        index, sign = np.asarray(mirror.index), np.asarray(mirror.sign, dtype=float)
        mean = np.zeros(len(index)) if mean is None else np.asarray(mean, dtype=float)
        std = np.ones(len(index)) if std is None else np.asarray(std, dtype=float)
        scale = sign * std[index] / std
        shift = (sign * mean[index] - mean) / std
        return NormalizedMirror(
            th.as_tensor(index, device=device),
            th.as_tensor(scale, dtype=th.float32, device=device),
            th.as_tensor(shift, dtype=th.float32, device=device),
        )


def mirror_loss(
    action_mean: Callable[[th.Tensor], th.Tensor],
    observations: th.Tensor,
    observation_mirror: NormalizedMirror,
    action_mirror: NormalizedMirror,
) -> th.Tensor:
    """Mean over the batch of the squared distance between the action mean on mirrored observations and
    the mirrored action mean; `action_mean` maps actor observations (batch, n) to action means."""
    both = action_mean(th.cat([observations, observation_mirror(observations)]))
    mean, on_mirrored = both.chunk(2)
    return ((on_mirrored - action_mirror(mean)) ** 2).sum(dim=-1).mean()
