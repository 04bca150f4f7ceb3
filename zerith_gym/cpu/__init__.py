"""The CPU backend: n robots on MuJoCo, one model and data per robot (`Simulator`), joined with the task in
one process (`ZerithBatch`) or over worker processes (`WorkerPool`). The MJX backend (`zerith_gym.mjx`)
runs the same task on JAX; both serve `zerith_gym.sb3.vec_env.ZerithVecEnv` through
`zerith_gym.core.contract`."""
