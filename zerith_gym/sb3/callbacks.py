"""Stable-Baselines3 callbacks for training on Zerith1-v0 (this module imports SB3; the package does not).

- `RewardTermsLogger` writes what the robot is paid for to the logger (tensorboard, csv, stdout), once per
  rollout, so that a user tuning reward weights sees which term moves.
- `RandomizationCurriculum` grows the training scenario's randomization, pushes and external forces from
  none to full during training, by timesteps, optionally gated by the fall rate.
- `TerrainCurriculum` moves each robot of a tile terrain (the `terrain` scenario) up a level when it walks
  far enough and down when it falls or falls short, and logs the mean level.
- `UpdateThreads` gives torch one thread while the robots are stepped and every core while the networks
  are updated, when the env's worker processes sleep (docs/performance.md has the gain).

From Python:

    from zerith_gym.sb3.callbacks import RandomizationCurriculum, RewardTermsLogger

    model.learn(8_000_000, callback=[RewardTermsLogger(), RandomizationCurriculum(steps=6_000_000)])

or in an RL Zoo hyperparameter file:

    callback:
      - zerith_gym.sb3.callbacks.RewardTermsLogger
      - zerith_gym.sb3.callbacks.RandomizationCurriculum:
          steps: 6000000
      - zerith_gym.sb3.callbacks.UpdateThreads

and on terrains (`env_kwargs: {scenario: terrain}`):

    callback:
      - zerith_gym.sb3.callbacks.TerrainCurriculum
"""

from __future__ import annotations

import math
import warnings
from collections import deque

import numpy as np
import torch as th
from stable_baselines3.common.callbacks import BaseCallback

from zerith_gym.core.infos import ended_falls
from zerith_gym.core.scenarios import Scenario, resolve_scenario, scaled_scenario
from zerith_gym.cpu.workers import available_cores
from zerith_gym.terrain.levels import LevelRule


class RewardTermsLogger(BaseCallback):
    """Per rollout: the mean episode sum of each reward term, the fall rate and the velocity errors.

    Logged keys: `terms/<term>` (mean over the episodes that ended during the rollout of the term's weighted
    episode sum, from `info["episode_terms"]`), `terms/fall_rate` (share of those episodes that ended in a
    fall), `terms/lin_vel_error` and `terms/ang_vel_error` (mean over every robot-step of the rollout).
    Works with any VecEnv of Zerith envs (`ZerithVecEnv`, or SB3's VecEnvs of `Zerith1Env`).
    """

    def __init__(self, verbose: int = 0) -> None:
        super().__init__(verbose)
        self._names: tuple[str, ...] | None = None
        """The env's reward terms (each robot's task has its own), read from the first ended episode."""
        self._reset()

    def _reset(self) -> None:
        self._episode_terms = np.zeros(len(self._names or ()))
        self._episodes = 0
        self._falls = 0
        self._errors = np.zeros(2)
        self._steps = 0

    def _on_rollout_start(self) -> None:
        self._reset()

    def _on_step(self) -> bool:
        infos, dones = self.locals["infos"], self.locals["dones"]
        step = getattr(infos, "step", None)  # a ZerithVecEnv's arrays (zerith_gym.core.infos.StepInfos)
        if step is not None:
            self._errors += (step.out.lin_vel_error.sum(), step.out.ang_vel_error.sum())
        else:
            self._errors += np.sum([(info["lin_vel_error"], info["ang_vel_error"]) for info in infos], axis=0)
        self._steps += len(infos)
        for i in np.flatnonzero(dones):
            info = infos[i]
            if "episode_terms" in info:
                terms = info["episode_terms"]
                if self._names is None:
                    self._names = tuple(terms)
                    self._episode_terms = np.zeros(len(self._names))
                self._episode_terms += [terms[name] for name in self._names]
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
            for name, total in zip(self._names or (), self._episode_terms / self._episodes, strict=True):
                self.logger.record(f"terms/{name}", float(total))


class RandomizationCurriculum(BaseCallback):
    """Train on `scaled_scenario(base, scale)` with `scale` rising from 0 to 1 in `stages` stages.

    By timesteps: over the first `steps` env steps of training (the model's `num_timesteps`, so a resumed
    run continues where it stopped), stage k of `stages` covers steps [k, k + 1) * steps / stages and
    trains at scale k / stages; from `steps` on, at scale 1 (the base scenario itself). With
    `max_fall_rate`, a stage is also held until at most that share of the last `gate_episodes` episodes
    that ended at this stage ended in a fall (a performance gate, as legged-robot curricula use), and the
    scale then rises by one stage at a time. The gate judges a window of episodes, not one rollout: a
    rollout of a few robots ends a handful of episodes, and a handful without a fall happens by chance at
    any fall rate. A stage's window starts empty (a resumed run refills it).

    `scenario`: the base (a name or a `Scenario`); default: the scenario the training env was made with.
    `start_stage`: the stage a resumed run had reached (its checkpoint's), from which the gate goes on.
    The change is made between rollouts through `set_scenario` of the env (`ZerithVecEnv`, or each
    `Zerith1Env` of another VecEnv): randomization ranges apply from each robot's next reset, forces,
    pushes and observation noise from the next step. Logs `curriculum/scale`.
    """

    def __init__(
        self,
        steps: int,
        stages: int = 8,
        scenario: str | Scenario | None = None,
        max_fall_rate: float | None = None,
        start_stage: int | None = None,
        gate_episodes: int = 100,
        verbose: int = 0,
    ) -> None:
        super().__init__(verbose)
        if not isinstance(steps, int | float) or steps < 0 or steps != int(steps):
            raise ValueError(f"curriculum steps must be a non-negative whole number, got {steps!r}")
        steps = int(steps)
        if not isinstance(stages, int) or stages < 1:
            raise ValueError(f"curriculum stages must be a positive integer, got {stages!r}")
        if max_fall_rate is not None and not 0.0 <= max_fall_rate <= 1.0:
            raise ValueError(f"max_fall_rate must be in [0, 1], got {max_fall_rate!r}")
        if not isinstance(gate_episodes, int) or gate_episodes < 1:
            raise ValueError(f"gate_episodes must be a positive integer, got {gate_episodes!r}")
        self.steps, self.stages, self.max_fall_rate = steps, stages, max_fall_rate
        self.base = None if scenario is None else resolve_scenario(scenario)
        if start_stage is not None and not (isinstance(start_stage, int) and 0 <= start_stage <= stages):
            raise ValueError(f"start_stage must be an integer in [0, stages={stages}], got {start_stage!r}")
        self.start_stage = start_stage
        self.stage: int | None = None
        self._falls: deque[bool] = deque(maxlen=gate_episodes)
        """Whether each of the stage's last `gate_episodes` ended episodes was a fall."""

    @property
    def scale(self) -> float:
        """The current randomization scale (0 before training starts)."""
        return 0.0 if self.stage is None else self.stage / self.stages

    def scheduled_stage(self, timesteps: int) -> int:
        """The stage the timestep schedule calls for after `timesteps` env steps (`stages` = full)."""
        if timesteps >= self.steps:
            return self.stages
        return math.floor(self.stages * timesteps / self.steps)

    def _on_training_start(self) -> None:
        if self.base is None:
            self.base = self.training_env.get_attr("scenario")[0]

    def _on_rollout_start(self) -> None:
        scheduled = self.scheduled_stage(self.model.num_timesteps)
        stage = scheduled
        previous = self.stage if self.stage is not None else self.start_stage
        if self.max_fall_rate is not None and previous is not None:
            window = self._falls
            settled = len(window) == window.maxlen and sum(window) <= self.max_fall_rate * len(window)
            stage = min(scheduled, previous + 1) if settled else min(scheduled, previous)
        if stage != self.stage:
            self.stage = stage
            scenario = self.base if stage == self.stages else scaled_scenario(self.base, self.scale)
            env = self.training_env.unwrapped
            if hasattr(env, "set_scenario"):
                env.set_scenario(scenario)
            else:
                env.env_method("set_scenario", scenario)
            if self.verbose:
                print(f"curriculum: scale {self.scale:g} at {self.num_timesteps} steps")
            self._falls.clear()
        self.logger.record("curriculum/scale", self.scale)

    def _on_step(self) -> bool:
        self._falls.extend(ended_falls(self.locals["dones"], self.locals["infos"]))
        return True


class TerrainCurriculum(BaseCallback):
    """Move robots between the levels of a tile terrain as their episodes end (`zerith_gym.terrain.levels`).

    At the start of training it hands the env a `LevelRule`: a robot moves up a level when it walked at
    least `promote_distance` m from its spawn point without falling (default: half a tile, to its tile's
    edge), down when it fell or walked less than `demote_fraction` of the distance its commands asked
    for; at the end of training the levels stay where they are and stop moving. The env applies the rule
    at each robot's reset, so the next episode starts on the new level. Logs `terrain/level` (the mean
    level the robots walked on in the rollout's last step) and `terrain/max_level_share` (the share at
    the top level). Works with `ZerithVecEnv` (cpu backend) and SB3's VecEnvs of `Zerith1Env`; ValueError
    at the start of training if the env's terrain has no tiles.
    """

    def __init__(
        self, promote_distance: float | None = None, demote_fraction: float = 0.5, verbose: int = 0
    ) -> None:
        super().__init__(verbose)
        self.rule = LevelRule(promote_distance, demote_fraction)
        self._levels: list[int] = []

    def _on_training_start(self) -> None:
        self._set_rule(self.rule)
        self._native = hasattr(self.training_env.unwrapped, "terrain_levels")  # ZerithVecEnv keeps them
        if not self._native and self.training_env.num_envs > 1:
            warnings.warn(
                "TerrainCurriculum: every Zerith1Env of this VecEnv is robot 0 and starts on the same tile "
                "(the first kind); make the env with zerith_gym.make_vec_env (RL Zoo does) to spread the "
                "robots over the kinds and start levels",
                stacklevel=2,
            )

    def _on_training_end(self) -> None:
        self._set_rule(None)

    def _set_rule(self, rule: LevelRule | None) -> None:
        env = self.training_env.unwrapped
        if hasattr(env, "set_level_rule"):
            env.set_level_rule(rule)
        else:
            env.env_method("set_level_rule", rule)

    def _on_step(self) -> bool:
        if not self._native:
            self._levels = [info["terrain_level"] for info in self.locals["infos"]]
        return True

    def _on_rollout_end(self) -> None:
        env = self.training_env.unwrapped
        levels = np.asarray(env.terrain_levels if self._native else self._levels)
        top = self.training_env.get_attr("scenario")[0].terrain.num_levels - 1
        self.logger.record("terrain/level", float(levels.mean()))
        self.logger.record("terrain/max_level_share", float((levels == top).mean()))


class UpdateThreads(BaseCallback):
    """Torch threads by phase: `collect` while robots are stepped, `update` from the rollout's last step on.

    While robots are stepped, the env's worker processes (or physics threads) use the cores, and a
    second torch thread only competes with them (its threads spin between operations); once the last
    step of a rollout is taken, the workers sleep and torch can use every core: for the last values and
    the returns, HuRiPPO's risk assessment of every state and its RND predictor's fit (which run before
    `on_rollout_end` reaches this callback), and the update. Default: 1 and every core. The thread count
    of before training is restored at its end. Works with any SB3 on-policy algorithm (whose rollout loop
    names `n_steps` and `n_rollout_steps`; otherwise the switch comes at `on_rollout_end`).
    """

    def __init__(self, collect: int = 1, update: int | None = None, verbose: int = 0) -> None:
        super().__init__(verbose)
        update = available_cores() if update is None else update
        for name, value in (("collect", collect), ("update", update)):
            if not isinstance(value, int) or value < 1:
                raise ValueError(f"UpdateThreads {name} must be a positive integer, got {value!r}")
        self.collect, self.update = collect, update
        self._before: int | None = None

    def _on_training_start(self) -> None:
        self._before = th.get_num_threads()

    def _on_rollout_start(self) -> None:
        th.set_num_threads(self.collect)

    def _on_rollout_end(self) -> None:
        th.set_num_threads(self.update)

    def _on_step(self) -> bool:
        n_steps, n_rollout_steps = self.locals.get("n_steps"), self.locals.get("n_rollout_steps")
        if n_steps is not None and n_rollout_steps is not None and n_steps + 1 >= n_rollout_steps:
            th.set_num_threads(self.update)  # the rollout's last step is taken: the rest is update work
        return True

    def _on_training_end(self) -> None:
        if self._before is not None:
            th.set_num_threads(self._before)
