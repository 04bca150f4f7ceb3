"""The callback that makes a run span sessions: its newest checkpoint between rollouts, and its curve.

``RunCheckpoint`` writes, every ``checkpoint_freq`` env steps and when training ends, the model and its
normalizer (``sb3_huri.runner.folder.save_run``), ``<env_id>/state.json`` and ``<env_id>/rng.pt``
(``sb3_huri.runner.state``), and a row of ``curve.csv`` after every rollout (``sb3_huri.runner.curve``).
``sb3_huri.runner.training.train_run`` reads them back: a resumed run restores the model, normalizer, random
states, curriculum stage and terrain levels (``start_on_levels``); its robots are reseeded from the run's
seed and step count, so resuming from a checkpoint is reproducible, though not the same draws as a run that
was never interrupted. Its episodes start afresh: an episode cut by the checkpoint moves no level, and a
robot whose episode ended in the checkpoint's very step goes on from the level it walked on.

Each checkpoint first keeps the one it replaces in ``<run>/.previous/`` (``sb3_huri.runner.fallback``):
a save that fails (a full disk) puts it back and raises, so the newest checkpoint is always a whole one,
and a newest one found damaged later is replaced by it.
"""

from __future__ import annotations

import contextlib
import os
import time
from pathlib import Path
from typing import Any

from sb3_huri.runner.curve import CurveWriter
from sb3_huri.runner.fallback import keep_previous, restore_previous, set_aside
from sb3_huri.runner.files import link_or_copy
from sb3_huri.runner.folder import CHECKPOINTS, save_run
from sb3_huri.runner.robustness import add_row, robustness_row
from sb3_huri.runner.state import RunState, hardware, save_random_states, terrain_levels
from zerith_gym import ZERITH1_ID


class RunCheckpoint(CurveWriter):
    """Writes the run's newest checkpoint between rollouts, every `checkpoint_freq` env steps and at the end,
    and its curve; optionally keeps copies and evaluates robustness rows as training passes their marks.

    A checkpoint is taken when a rollout starts (after the previous one's update), so the model it saves
    has learnt from exactly the steps it counts. A stop request or the wall-time limit lets the rollout
    under way finish and learn, then checkpoints and ends training.

    :param run: the run folder (RL Zoo's layout)
    :param preset: the hyperparameters (``config.yml``)
    :param run_args: the run's arguments (``args.yml``)
    :param checkpoint_freq: env steps between checkpoints
    :param curriculum: the run's curriculum callback, whose stage is saved (None: no curriculum)
    :param max_wall_s: stop training (with a checkpoint) after this many seconds of this session
    :param keep_every: keep a copy of the checkpoint in ``checkpoints/`` each time training passes a
        multiple of this many steps (``rl_model_<steps>_steps.zip`` and ``rl_model_vecnormalize_...pkl``)
    :param robustness: a ``sb3_huri.runner.training.RobustnessSchedule``: each time training passes a
        multiple of its `every` steps, the checkpoint is kept and evaluated into ``robustness.csv`` (the
        evaluation's time is not counted as training time)
    """

    def __init__(
        self,
        run: str | os.PathLike,
        preset: dict[str, Any],
        run_args: dict[str, Any],
        checkpoint_freq: int,
        curriculum: Any | None = None,
        max_wall_s: float | None = None,
        env_id: str = ZERITH1_ID,
        verbose: int = 0,
        keep_every: int | None = None,
        robustness: Any | None = None,
    ) -> None:
        super().__init__(run, curriculum, verbose)
        for name, value in (("checkpoint_freq", checkpoint_freq), ("keep_every", keep_every or 1)):
            if not isinstance(value, int) or value < 1:
                raise ValueError(f"{name} must be a positive number of env steps, got {value!r}")
        self.run, self.preset, self.run_args = Path(run), preset, run_args
        self.checkpoint_freq, self.max_wall_s = checkpoint_freq, max_wall_s
        self.keep_every, self.robustness = keep_every, robustness
        self.env_id = env_id
        self.state = RunState.read(self.run, env_id)
        self.saved_steps = self.state.timesteps
        """Steps of the newest checkpoint written."""
        self._began = 0.0
        self._paused_s = 0.0
        self._session: dict[str, Any] = {}
        self._stop_requested = self._stopping = False

    def request_stop(self) -> None:
        """End training after the rollout under way, with a checkpoint (e.g. from a SIGTERM handler)."""
        self._stop_requested = True

    @property
    def wall_s(self) -> float:
        """Training wall time of the run so far, all sessions (evaluations left out)."""
        return self.state.wall_s + time.time() - self._began - self._paused_s

    def _on_training_start(self) -> None:
        super()._on_training_start()
        self._began = time.time()
        self.saved_steps = self.num_timesteps
        self._session = {
            "started": time.strftime("%Y-%m-%d %H:%M:%S"),
            "from_timesteps": self.num_timesteps,
            "hardware": hardware(),
        }
        self.state.sessions.append(self._session)

    def _passed(self, every: int | None) -> bool:
        return every is not None and self.num_timesteps // every > self.saved_steps // every

    def _on_rollout_start(self) -> None:
        if self.num_timesteps == self.saved_steps:
            return
        wall_reached = self.max_wall_s is not None and time.time() - self._began >= self.max_wall_s
        self._stopping = self._stop_requested or wall_reached
        self._checkpoint(force=self._stopping)

    def _on_step(self) -> bool:
        super()._on_step()
        return not self._stopping

    def _on_training_end(self) -> None:
        if not self._stopping:  # a stop has saved already, one env step before this
            self._checkpoint(force=True)

    def _checkpoint(self, force: bool) -> None:
        """Save when due (or `force`), keep a copy and add a robustness row when training passed a mark."""
        every = getattr(self.robustness, "every", None)
        keep, row = self._passed(self.keep_every) or self._passed(every), self._passed(every)
        if force or keep or self.num_timesteps - self.saved_steps >= self.checkpoint_freq:
            self.save()
        if keep:
            self.keep_copy()
        if row:
            self.add_robustness_row()

    def keep_copy(self) -> None:
        """Keep the newest checkpoint's model and normalizer in ``checkpoints/`` under its steps (a second
        name for each file, written whole: a failure leaves no torn copy)."""
        kept = self.run / CHECKPOINTS
        steps = self.saved_steps
        link_or_copy(self.run / f"{self.env_id}.zip", kept / f"rl_model_{steps}_steps.zip")
        normalizer = self.run / self.env_id / "vecnormalize.pkl"
        if normalizer.is_file():
            link_or_copy(normalizer, kept / f"rl_model_vecnormalize_{steps}_steps.pkl")

    def add_robustness_row(self) -> None:
        """Evaluate the model as it is now (the newest checkpoint) into the run's ``robustness.csv``."""
        began = time.time()
        schedule = self.robustness
        metrics = robustness_row(
            self.model,
            self.model.get_vec_normalize_env(),
            schedule.episodes,
            schedule.seed,
            episode_steps=schedule.episode_steps,
        )
        row = add_row(self.run, self.saved_steps, metrics, schedule.episodes)
        self._paused_s += time.time() - began
        if self.verbose:
            print(f"robustness at {self.saved_steps} steps: Table-1 mean {row['table1_mean']}", flush=True)

    def save(self) -> None:
        """Model, normalizer, preset, arguments, state and random states, replacing the previous ones, which
        are kept in ``<run>/.previous/``. A save that fails puts them back (an unfinished first one
        is set aside), then raises: the newest checkpoint is always a complete one."""
        kept = keep_previous(self.run, self.env_id)
        try:
            self._write()
        except BaseException:
            with contextlib.suppress(OSError):
                if not restore_previous(self.run, self.env_id) and not kept:
                    set_aside(self.run, self.env_id, "unfinished")
            raise

    def _write(self) -> None:
        """Write the checkpoint's files, ``state.json`` last."""
        wall = self.wall_s
        stepped = self.num_timesteps > self._session.get("from_timesteps", self.num_timesteps)
        save_run(self.model, self.run, self.preset, self.run_args, self.env_id)
        self._session.update(
            to_timesteps=self.num_timesteps, wall_s=round(time.time() - self._began - self._paused_s, 1)
        )
        state = RunState(
            timesteps=self.num_timesteps,
            curriculum_stage=getattr(self.curriculum, "stage", None),
            # Before this session's first step the env has not reported its robots' levels yet.
            terrain_levels=terrain_levels(self.training_env) if stepped else self.state.terrain_levels,
            wall_s=round(wall, 1),
            sessions=self.state.sessions,
        )
        save_random_states(self.run, self.env_id)
        state.write(self.run, self.env_id)  # last: the checkpoint is complete
        self.saved_steps = self.num_timesteps
        if self.verbose:
            print(
                f"checkpoint: {self.num_timesteps} steps, {wall:.0f} s of training, in {self.run}", flush=True
            )
