"""Batches of observations in numpy, for ``Box`` (arrays) and ``Dict`` (dicts of arrays) spaces alike.

A rollout's end gathers states of different origins (the envs' next observations, the final observations of
truncated episodes, one at a time) into one batch, so that the critic reads them all in one pass.
"""

from typing import Any

import numpy as np
import torch as th


def to_numpy(tensor: th.Tensor) -> np.ndarray:
    """A detached CPU copy of `tensor` as a numpy array."""
    return tensor.detach().cpu().numpy()


def add_batch_axis(obs: np.ndarray | dict[str, np.ndarray]) -> np.ndarray | dict[str, np.ndarray]:
    """One observation as a batch of one (each entry of a ``Dict`` observation)."""
    if isinstance(obs, dict):
        return {key: np.asarray(value)[None] for key, value in obs.items()}
    return np.asarray(obs)[None]


def concatenate_observations(batches: list[Any]) -> np.ndarray | dict[str, np.ndarray]:
    """Batches of observations, all arrays or all dicts with the same keys, as one batch in order."""
    if isinstance(batches[0], dict):
        return {key: np.concatenate([batch[key] for batch in batches]) for key in batches[0]}
    return np.concatenate(batches)
