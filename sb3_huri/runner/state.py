"""What a run's checkpoint records beside its model: progress, sessions, random states and terrain levels.

``<run>/<env_id>/state.json`` (``RunState``) holds the steps, the curriculum's stage, on a tile terrain each
robot's terrain level, the training wall time of all sessions, and one entry per training session (when,
from and to which step, wall time, hardware), so a run's cost adds up honestly across sessions.
``<run>/<env_id>/rng.pt`` holds the random states of torch, numpy and Python at the checkpoint.
"""

from __future__ import annotations

import json
import os
import platform
import random
import warnings
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import torch as th
from stable_baselines3.common.vec_env import VecEnv

from sb3_huri.runner.files import RunError, read_json, replaced, write_text
from zerith_gym import ZERITH1_ID

STATE_FILE = "state.json"
RANDOM_STATES_FILE = "rng.pt"


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
    def read(run: str | os.PathLike, env_id: str = ZERITH1_ID) -> RunState:
        """The run's state, or a new one if the run has none yet; RunError naming the file if it is not a
        run's state (not JSON, or not the fields of one)."""
        path = Path(run) / env_id / STATE_FILE
        if not path.is_file():
            return RunState()
        what = "a run's training state"
        data = read_json(path, what)
        try:
            state = RunState(**data)
        except TypeError as error:
            raise RunError(f"{path} is corrupt ({error}); it should hold {what}") from None
        if not isinstance(state.timesteps, int) or not isinstance(state.sessions, list):
            raise RunError(f"{path} is corrupt (timesteps {state.timesteps!r}); it should hold {what}")
        return state

    def write(self, run: str | os.PathLike, env_id: str = ZERITH1_ID) -> None:
        """Replace the run's ``state.json`` (atomically: written last, it completes a checkpoint)."""
        write_text(Path(run) / env_id / STATE_FILE, json.dumps(asdict(self), indent=1) + "\n")

    def hardware_until(self, steps: int) -> list[str]:
        """The machines of the sessions that trained the run before `steps`, each named once."""
        names = [s.get("hardware", "unknown") for s in self.sessions if s.get("from_timesteps", 0) < steps]
        return list(dict.fromkeys(names))

    def hardware_at(self, steps: int) -> str:
        """The machine of the session that reached `steps`, or "unknown"."""
        for session in self.sessions:
            if session["from_timesteps"] < steps <= session.get("to_timesteps", steps):
                return session["hardware"]
        return "unknown"


def hardware() -> str:
    """This machine in a few words: processor, cores, torch device."""
    device = th.cuda.get_device_name(0) if th.cuda.is_available() else "no GPU"
    names = dict.fromkeys(name for name in (platform.machine(), platform.processor()) if name)  # often equal
    return f"{' '.join(names)} {os.cpu_count()} cores, {device}".strip()


def save_random_states(run: str | os.PathLike, env_id: str = ZERITH1_ID) -> None:
    """Save the random states of torch, numpy and Python with the run's checkpoint."""
    states = {"torch": th.get_rng_state(), "numpy": np.random.get_state(), "python": random.getstate()}  # noqa: NPY002
    with replaced(Path(run) / env_id / RANDOM_STATES_FILE) as temporary:
        th.save(states, temporary)


def restore_random_states(run: str | os.PathLike, env_id: str = ZERITH1_ID) -> bool:
    """Restore torch, numpy and Python random states saved with the run's checkpoint; False if none."""
    path = Path(run) / env_id / RANDOM_STATES_FILE
    if not path.is_file():
        return False
    states = th.load(path, weights_only=False)
    th.set_rng_state(states["torch"])
    np.random.set_state(states["numpy"])  # noqa: NPY002 (SB3 shuffles minibatches with the global state)
    random.setstate(states["python"])
    return True


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
    ``i % columns``, as `zerith_gym.terrain.levels` places them). With another number of robots than
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
