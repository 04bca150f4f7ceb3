"""Shared pytest configuration: headless rendering and quiet, single-threaded torch."""

import os

os.environ.setdefault("MUJOCO_GL", "egl")

import torch

# Tests run in parallel workers on small machines: one intra-op thread each avoids oversubscription.
torch.set_num_threads(1)
