"""The array namespace of the task code: numpy on the CPU backend, jax.numpy on the MJX backend.

The task's math (observations, rewards, randomization, disturbances, terrain heights) is written once,
against the functions that numpy and jax.numpy share, without in-place writes. Each function takes
its namespace from its inputs with `namespace`, so the same lines run on numpy arrays in the CPU env
and are traced by `jax.jit` in the MJX env.
"""

from __future__ import annotations

import sys
from types import ModuleType
from typing import Any

import numpy as np


def is_jax(array: Any) -> bool:
    """Whether `array` is a JAX array (or tracer), without importing JAX when it is not loaded."""
    jax = sys.modules.get("jax")
    return jax is not None and isinstance(array, jax.Array)


def namespace(*arrays: Any) -> ModuleType:
    """jax.numpy if any of `arrays` is a JAX array, else numpy."""
    if any(is_jax(array) for array in arrays):
        import jax.numpy as jnp

        return jnp
    return np
