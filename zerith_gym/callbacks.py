"""Stable-Baselines3 callbacks for training on Zerith1-v0 (this module imports SB3; the package does not).

`RewardTermsLogger` writes what the robot is paid for to the logger (tensorboard, csv, stdout), once per
rollout, so that a user tuning reward weights sees which term moves:

    from zerith_gym.callbacks import RewardTermsLogger

    model.learn(1_000_000, callback=RewardTermsLogger())

or in an RL Zoo hyperparameter file: `callback: zerith_gym.callbacks.RewardTermsLogger`.
"""

from __future__ import annotations

import numpy as np
from stable_baselines3.common.callbacks import BaseCallback

from zerith_gym.rewards import REWARD_NAMES


class RewardTermsLogger(BaseCallback):
    """Per rollout: the mean episode sum of each reward term, the fall rate and the velocity errors.

    Logged keys: `terms/<term>` (mean over the episodes that ended during the rollout of the term's weighted
    episode sum, from `info["episode_terms"]`), `terms/fall_rate` (share of those episodes that ended in a
    fall), `terms/lin_vel_error` and `terms/ang_vel_error` (mean over every robot-step of the rollout).
    Works with any VecEnv of Zerith envs (`ZerithVecEnv`, or SB3's VecEnvs of `Zerith1Env`).
    """

    def __init__(self, verbose: int = 0) -> None:
        super().__init__(verbose)
        self._reset()

    def _reset(self) -> None:
        self._episode_terms = np.zeros(len(REWARD_NAMES))
        self._episodes = 0
        self._falls = 0
        self._errors = np.zeros(2)
        self._steps = 0

    def _on_rollout_start(self) -> None:
        self._reset()

    def _on_step(self) -> bool:
        for info, done in zip(self.locals["infos"], self.locals["dones"], strict=True):
            self._errors += (info["lin_vel_error"], info["ang_vel_error"])
            self._steps += 1
            if done and "episode_terms" in info:
                self._episode_terms += [info["episode_terms"][name] for name in REWARD_NAMES]
                self._episodes += 1
                self._falls += bool(info["fall"])
        return True

    def _on_rollout_end(self) -> None:
        if self._steps:
            lin_error, ang_error = self._errors / self._steps
            self.logger.record("terms/lin_vel_error", float(lin_error))
            self.logger.record("terms/ang_vel_error", float(ang_error))
        if self._episodes:
            self.logger.record("terms/fall_rate", self._falls / self._episodes)
            for name, total in zip(REWARD_NAMES, self._episode_terms / self._episodes, strict=True):
                self.logger.record(f"terms/{name}", float(total))
