"""The MJX (JAX) backend of Zerith1-v0: thousands of robots on a GPU, the same task as the CPU backend.

    import zerith_gym

    env = zerith_gym.make_vec_env(4096, seed=0, backend="mjx")  # an SB3 VecEnv, like the CPU one

Needs the optional dependencies (`pip install "sb3-huri[mjx]"`: jax and mujoco-mjx); JAX runs on its
default device, the GPU where one is installed, else the CPU (slow, but the tests run there).
docs/gpu.md says how the task code is shared with the CPU backend and what differs.
"""

from zerith_gym.mjx.batch import MjxBatch, MjxState
from zerith_gym.mjx.physics import MjxPhysics, SolverSettings

__all__ = ["MjxBatch", "MjxPhysics", "MjxState", "SolverSettings"]
