"""What Stable-Baselines3 and RL Zoo see of the env: the robots as one SB3 `VecEnv` (`vec_env`:
`ZerithVecEnv`, `make_vec_env`) and the training callbacks the presets name (`callbacks`: the curricula,
the reward-term logs, the update's threads).

The env itself (the task, its two backends, the Gymnasium envs) does not import SB3 or torch; these
modules do, and are imported on first use (`zerith_gym.make_vec_env`).
"""
