"""A symmetry loss on the actor: act on a mirrored observation as on the original, mirrored.

An env whose task is left-right symmetric (Zerith1-v0: `zerith_gym.zerith1.symmetry`) gives two signed
permutations, `policy_mirror` of the actor's observation and `action_mirror` of the action (objects with
`index` and `sign` arrays: ``mirrored[..., i] = sign[i] * x[..., index[i]]``). The loss is the mean over the
minibatch of ``|mu(mirror(o)) - action_mirror(mu(o))|^2``, with ``mu`` the actor's action mean: a symmetric
policy scores 0. The actor sees normalized observations (`VecNormalize`), so the mirror is carried into
normalized units: ``normalize(mirror(x)) = scale * x_normalized[index] + shift`` (clipping aside).
:func:`env_mirrors` reads both maps from the env and carries the observation's into the units of its
``VecNormalize``.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, NamedTuple

import numpy as np
import torch as th
from gymnasium import spaces
from stable_baselines3.common.vec_env import VecEnv, VecNormalize


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


def env_mirrors(
    env: VecEnv,
    observation_space: spaces.Space,
    normalizer: VecNormalize | None,
    actor_key: str,
    device: th.device | str = "cpu",
) -> tuple[NormalizedMirror, NormalizedMirror]:
    """The env's mirror of the actor's observation (`actor_key`'s entry of a ``Dict`` observation, the
    whole of a ``Box`` one), in the units `normalizer` gives it (its statistics now), and its mirror of the
    action; ValueError if the env has none."""
    try:
        observation, action = (env.get_attr(name, [0])[0] for name in ("policy_mirror", "action_mirror"))
    except AttributeError as error:
        raise ValueError(
            "mirror_coef > 0 needs an env with `policy_mirror` and `action_mirror` maps of the actor's "
            "observation and of the action (Zerith1-v0 has them: zerith_gym.zerith1.symmetry)"
        ) from error
    is_dict = isinstance(observation_space, spaces.Dict)
    if is_dict and actor_key not in observation_space.spaces:
        raise ValueError(f"mirror_coef > 0 needs the actor's own {actor_key!r} observation entry")
    mean = std = None
    if normalizer is not None and normalizer.norm_obs:
        if not is_dict:
            mean, std = normalizer.obs_rms.mean, np.sqrt(normalizer.obs_rms.var + normalizer.epsilon)
        elif actor_key in normalizer.norm_obs_keys:
            stats = normalizer.obs_rms[actor_key]
            mean, std = stats.mean, np.sqrt(stats.var + normalizer.epsilon)
    return (
        NormalizedMirror.build(observation, mean, std, device),
        NormalizedMirror.build(action, device=device),
    )
