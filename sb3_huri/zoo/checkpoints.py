"""Training that spans sessions: the newest checkpoint of a run, its learning curve, and resuming it.

A run folder in RL Zoo's layout (``sb3_huri.zoo.runs``) gets, besides the model and its normalizer:

- ``<env_id>/state.json``: steps, the curriculum's stage, on a tile terrain each robot's terrain level, and
  one entry per training session (when, how many steps, wall time, hardware), so a run's cost adds up
  honestly across sessions;
- ``<env_id>/rng.pt``: the random states of torch, numpy and Python at the checkpoint;
- ``curve.csv``: one row per rollout (``sb3_huri.zoo.curve``: steps, cumulative wall time, episode length and
  return, fall rate, curriculum scale, and the previous update's KL, clip fraction, explained variance,
  action noise and learning rates), written by ``CurveWriter``, which the experiment grid's runs use too.

``RunCheckpoint`` writes them every ``every_steps`` env steps and when training ends; ``resume_state`` reads
them back. A resumed run restores the model, normalizer, random states, curriculum stage and terrain levels
(`start_on_levels`); its robots are reseeded from the run's seed and step count, so resuming from a
checkpoint is reproducible, though not the same draws as a run that was never interrupted. Its episodes
start afresh: an episode cut by the checkpoint moves no level, and a robot whose episode ended in the
checkpoint's very step goes on from the level it walked on.
"""

from __future__ import annotations

import json
import os
import platform
import random
import time
import warnings
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import torch as th
from stable_baselines3.common.callbacks import BaseCallback
from stable_baselines3.common.vec_env import VecEnv

from sb3_huri.zoo.curve import CURVE_COLUMNS, RISK_COLUMNS, append_row, trim_curve
from sb3_huri.zoo.runs import DEFAULT_ENV_ID, save_run
from zerith_gym.infos import ended_falls

_TRAIN_COLUMNS = CURVE_COLUMNS[6:12]


def update_figures(model: Any) -> dict[str, float]:
    """The recent episodes' mean length and return, and the previous update's figures (SB3's logger holds
    them until the next dump, so read them at the end of a rollout; NaN where not logged)."""
    values = model.logger.name_to_value
    episodes = list(model.ep_info_buffer)
    return {
        "ep_len": float(np.mean([e["l"] for e in episodes])) if episodes else np.nan,
        "ep_return": float(np.mean([e["r"] for e in episodes])) if episodes else np.nan,
        **{key: float(values.get(f"train/{key}", np.nan)) for key in _TRAIN_COLUMNS},
    }


def risk_figures(model: Any) -> dict[str, float]:
    """The rollout's risk levels in use (``RISK_COLUMNS``), as the algorithm logged them at its end; empty
    for a scalar critic, and NaN for a figure it does not log (the RND part without RND)."""
    values = model.logger.name_to_value
    if "rollout/risk_mean" not in values:
        return {}
    return {column: float(values.get(key, np.nan)) for column, key in RISK_COLUMNS.items()}


class UpdateRecorder(BaseCallback):
    """Keeps a row per update in `rows`: steps and `update_figures` (for benchmarks comparing settings)."""

    def __init__(self) -> None:
        super().__init__()
        self.rows: list[dict[str, float]] = []

    def _on_step(self) -> bool:
        return True

    def _on_rollout_end(self) -> None:
        if "train/approx_kl" in self.model.logger.name_to_value:
            self.rows.append({"timesteps": self.num_timesteps, **update_figures(self.model)})


@dataclass
class RunState:
    """What a checkpoint records beside the model: progress, curriculum stage and the sessions so far."""

    timesteps: int = 0
    curriculum_stage: int | None = None
    terrain_levels: list[int] | None = None
    """On a tile terrain, the level each robot walked on in the last step (`terrain_levels`)."""
    wall_s: float = 0.0
    sessions: list[dict[str, Any]] = field(default_factory=list)

    @staticmethod
    def read(run: str | os.PathLike, env_id: str = DEFAULT_ENV_ID) -> RunState:
        """The run's state, or a new one if the run has none yet."""
        path = Path(run) / env_id / "state.json"
        return RunState(**json.loads(path.read_text())) if path.is_file() else RunState()


def terrain_levels(env: VecEnv) -> list[int] | None:
    """The terrain level (tile row) each robot of `env` walked on in its last step, if `env` is (or wraps) a
    `ZerithVecEnv` on a tile terrain; None otherwise (nothing to restore)."""
    base = env.unwrapped
    scenario = getattr(base, "scenario", None)
    if getattr(scenario, "terrain", None) is None or scenario.terrain.tiles is None:
        return None
    return [int(level) for level in getattr(base, "terrain_levels", [])] or None


def start_on_levels(env: VecEnv, levels: list[int]) -> bool:
    """Start `env`'s robots on `levels` at its next reset, each in its own kind column (robot i in column
    ``i % columns``, as `zerith_gym.terrain_levels` places them). With another number of robots than
    `levels` has, a warning, and the robots start from the terrain's start levels (False)."""
    if len(levels) != env.num_envs:
        warnings.warn(
            f"{len(levels)} terrain levels saved, but the env has {env.num_envs} robots: they start from the "
            "terrain's start levels",
            stacklevel=2,
        )
        return False
    columns = env.unwrapped.scenario.terrain.num_columns
    env.set_options([{"tile": (level, i % columns)} for i, level in enumerate(levels)])
    return True


def _mean_level(env: VecEnv) -> float:
    """The robots' mean terrain level (tile row) now; NaN off tile terrains."""
    levels = terrain_levels(env)
    return float(np.mean(levels)) if levels else np.nan


def hardware() -> str:
    """This machine in a few words: processor, cores, torch device."""
    device = th.cuda.get_device_name(0) if th.cuda.is_available() else "no GPU"
    names = dict.fromkeys(name for name in (platform.machine(), platform.processor()) if name)  # often equal
    return f"{' '.join(names)} {os.cpu_count()} cores, {device}".strip()


def restore_random_states(run: str | os.PathLike, env_id: str = DEFAULT_ENV_ID) -> bool:
    """Restore torch, numpy and Python random states saved with the run's checkpoint; False if none."""
    path = Path(run) / env_id / "rng.pt"
    if not path.is_file():
        return False
    states = th.load(path, weights_only=False)
    th.set_rng_state(states["torch"])
    np.random.set_state(states["numpy"])  # noqa: NPY002 (SB3 shuffles minibatches with the global state)
    random.setstate(states["python"])
    return True


class CurveWriter(BaseCallback):
    """After every rollout, a row of the run's learning curve (`sb3_huri.zoo.curve`) in `folder`.

    When training starts, the rows past the model's step count are dropped (a resumed run trains those steps
    again). Subclasses say what the run's training wall time is (`wall_s`, all sessions).

    :param folder: where `curve.csv` is
    :param curriculum: the run's randomization curriculum (its `scale` is recorded), or None (scale 1)
    """

    def __init__(self, folder: str | os.PathLike, curriculum: Any | None = None, verbose: int = 0) -> None:
        super().__init__(verbose)
        self.folder, self.curriculum = Path(folder), curriculum
        self._episodes = self._falls = 0

    @property
    def wall_s(self) -> float:
        """Training wall time of the run so far (seconds, all sessions)."""
        raise NotImplementedError

    def _on_training_start(self) -> None:
        trim_curve(self.folder, self.num_timesteps)

    def _on_step(self) -> bool:
        falls = ended_falls(self.locals["dones"], self.locals["infos"])
        self._episodes += len(falls)
        self._falls += sum(falls)
        return True

    def _on_rollout_end(self) -> None:
        figures = update_figures(self.model)
        append_row(
            self.folder,
            {
                "timesteps": self.num_timesteps,
                "wall_s": round(self.wall_s, 1),
                "ep_len": figures.pop("ep_len"),
                "ep_return": figures.pop("ep_return"),
                "fall_rate": self._falls / self._episodes if self._episodes else np.nan,
                "scale": self.curriculum.scale if self.curriculum is not None else 1.0,
                **figures,
                "terrain_level": _mean_level(self.training_env),
                **risk_figures(self.model),
            },
        )
        self._episodes = self._falls = 0


class RunCheckpoint(CurveWriter):
    """Writes the run's newest checkpoint between rollouts, every `every_steps` env steps and at the end,
    and its curve; optionally keeps copies and evaluates robustness rows as training passes their marks.

    A checkpoint is taken when a rollout starts (after the previous one's update), so the model it saves
    has learnt from exactly the steps it counts. A stop request or the wall-time limit lets the rollout
    under way finish and learn, then checkpoints and ends training.

    :param run: the run folder (RL Zoo's layout)
    :param preset: the hyperparameters (``config.yml``)
    :param run_args: the run's arguments (``args.yml``)
    :param every_steps: env steps between checkpoints
    :param curriculum: the run's curriculum callback, whose stage is saved (None: no curriculum)
    :param max_wall_s: stop training (with a checkpoint) after this many seconds of this session
    :param keep_every: keep a copy of the checkpoint in ``checkpoints/`` each time training passes a
        multiple of this many steps (``rl_model_<steps>_steps.zip`` and ``rl_model_vecnormalize_...pkl``)
    :param robustness: a ``sb3_huri.experiments.trainer.RobustnessSchedule``: each time training passes a
        multiple of its `every` steps, the checkpoint is kept and evaluated into ``robustness.csv`` (the
        evaluation's time is not counted as training time)
    """

    def __init__(
        self,
        run: str | os.PathLike,
        preset: dict[str, Any],
        run_args: dict[str, Any],
        every_steps: int,
        curriculum: Any | None = None,
        max_wall_s: float | None = None,
        env_id: str = DEFAULT_ENV_ID,
        verbose: int = 0,
        keep_every: int | None = None,
        robustness: Any | None = None,
    ) -> None:
        super().__init__(run, curriculum, verbose)
        for name, value in (("every_steps", every_steps), ("keep_every", keep_every or 1)):
            if not isinstance(value, int) or value < 1:
                raise ValueError(f"{name} must be a positive number of env steps, got {value!r}")
        self.run, self.preset, self.run_args = Path(run), preset, run_args
        self.every_steps, self.max_wall_s = every_steps, max_wall_s
        self.keep_every, self.robustness = keep_every, robustness
        if robustness is not None:  # imported now: a module changed on disk later must not mix in mid-run
            from sb3_huri.experiments import robustness as robustness_rows

            self._rows = robustness_rows
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
        if force or keep or self.num_timesteps - self.saved_steps >= self.every_steps:
            self.save()
        if keep:
            self.keep_copy()
        if row:
            self.add_robustness_row()

    def keep_copy(self) -> None:
        """Copy the newest checkpoint's model and normalizer into ``checkpoints/`` under its steps."""
        import shutil

        kept = self.run / "checkpoints"
        kept.mkdir(exist_ok=True)
        steps = self.saved_steps
        shutil.copyfile(self.run / f"{self.env_id}.zip", kept / f"rl_model_{steps}_steps.zip")
        normalizer = self.run / self.env_id / "vecnormalize.pkl"
        if normalizer.is_file():
            shutil.copyfile(normalizer, kept / f"rl_model_vecnormalize_{steps}_steps.pkl")

    def add_robustness_row(self) -> None:
        """Evaluate the model as it is now (the newest checkpoint) into the run's ``robustness.csv``."""
        began = time.time()
        schedule = self.robustness
        metrics = self._rows.robustness_row(
            self.model,
            self.model.get_vec_normalize_env(),
            schedule.episodes,
            schedule.seed,
            episode_steps=schedule.episode_steps,
        )
        row = self._rows.add_row(self.run, self.saved_steps, metrics, schedule.episodes)
        self._paused_s += time.time() - began
        if self.verbose:
            print(f"robustness at {self.saved_steps} steps: Table-1 mean {row['table1_mean']}", flush=True)

    def save(self) -> None:
        """Model, normalizer, preset, arguments, state and random states, replacing the previous ones."""
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
        folder = self.run / self.env_id
        (folder / ".state.saving").write_text(json.dumps(asdict(state), indent=1) + "\n")
        th.save(
            {"torch": th.get_rng_state(), "numpy": np.random.get_state(), "python": random.getstate()},  # noqa: NPY002
            folder / ".rng.saving",
        )
        os.replace(folder / ".rng.saving", folder / "rng.pt")
        os.replace(folder / ".state.saving", folder / "state.json")  # last: the checkpoint is complete
        self.saved_steps = self.num_timesteps
        if self.verbose:
            print(
                f"checkpoint: {self.num_timesteps} steps, {wall:.0f} s of training, in {self.run}", flush=True
            )
