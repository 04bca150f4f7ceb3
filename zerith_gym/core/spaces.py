"""The spaces of the Zerith envs and what crosses them: observation and action spaces, the observation as an
`obs_mode` gives it, and the check every action goes through."""

from __future__ import annotations

from typing import Any

import numpy as np
from gymnasium import spaces

from zerith_gym.core.spec import RobotSpec
from zerith_gym.core.task import LocomotionTask


def observation_space(obs_mode: str, task: LocomotionTask) -> spaces.Space:
    """The observation space of one robot of `task` for `obs_mode`."""
    policy = spaces.Box(-np.inf, np.inf, shape=(task.policy_size,), dtype=np.float32)
    if obs_mode == "policy":
        return policy
    critic = spaces.Box(-np.inf, np.inf, shape=(task.critic_size,), dtype=np.float32)
    return spaces.Dict({"policy": policy, "critic": critic})


def format_observation(obs_mode: str, policy: np.ndarray, critic: np.ndarray) -> Any:
    """The observation as `obs_mode` gives it, from the policy and critic parts (one robot or a batch)."""
    if obs_mode == "policy":
        return policy
    return {"policy": policy, "critic": critic}


def action_space(robot: RobotSpec) -> spaces.Box:
    """One robot's actions: a joint-position offset per joint, in units of its action scale, within
    +-`robot.action_clip` (Zerith-1: 1; the quadruped: legged_gym's 100)."""
    bound = robot.action_clip
    return spaces.Box(-bound, bound, shape=(robot.num_joints,), dtype=np.float32)


def check_actions(actions: Any, shape: tuple[int, ...], clip: float = 1.0) -> np.ndarray:
    """Actions as float64 of `shape`, clipped to [-clip, clip]; ValueError on a wrong shape or non-finite
    values."""
    actions = np.array(actions, dtype=np.float64)
    if actions.shape != shape:
        raise ValueError(f"action must have shape {shape}, got {actions.shape}")
    if not np.isfinite(actions).all():
        raise ValueError(f"action contains NaN or infinite values: {actions}")
    return np.minimum(
        np.maximum(actions, -clip, out=actions), clip, out=actions
    )  # np.clip, without its overhead
