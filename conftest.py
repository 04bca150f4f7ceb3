"""Shared pytest configuration of the library's tests (tests/) and the study's (study/tests/): headless
rendering, quiet single-threaded torch, and one JAX compilation cache."""

import os

os.environ.setdefault("MUJOCO_GL", "egl")

import torch

# Tests run in parallel workers on small machines: one intra-op thread each avoids oversubscription.
torch.set_num_threads(1)

# JAX (the MJX backend's tests) compiles the env's step once per shape: keep the compiled programs
# on disk for this run, so that subprocesses (the RL Zoo test) reuse them.
os.environ.setdefault(
    "JAX_COMPILATION_CACHE_DIR", os.path.join(os.path.dirname(__file__), ".pytest_jax_cache")
)
