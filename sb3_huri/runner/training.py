"""The one trainer of every run: start or resume a run folder, train it, checkpoint it between rollouts.

``train_run`` is what the experiment grid, the campaign (``python -m sb3_huri.experiments run|campaign``)
and ``examples/train_zerith.py`` run. It trains what ``rl_zoo3 train --algo <method> --env
Zerith1-v0 -conf <preset>`` trains (the preset's batched env, normalizer, model and ``callback:`` entries,
read as RL Zoo reads them) and adds what a run spanning many sessions needs. A run folder, in RL Zoo's
layout so that RL Zoo's tools read it::

    <run>/Zerith1-v0.zip                      the newest checkpoint's model
    <run>/Zerith1-v0/config.yml, args.yml     the preset and the run's arguments (method, seed, env options)
    <run>/Zerith1-v0/vecnormalize.pkl         its normalizer
    <run>/Zerith1-v0/state.json, rng.pt       steps, curriculum stage, terrain levels, sessions; random states
    <run>/curve.csv                           a row per rollout (sb3_huri.runner.curve)
    <run>/robustness.csv                      Table-1 survival every few million steps (robustness)
    <run>/checkpoints/rl_model_<steps>_steps.zip, rl_model_vecnormalize_<steps>_steps.pkl   kept copies
    <run>/evaluations/<steps>.json            evaluations of its checkpoints (sb3_huri.runner.record)

Checkpoints are taken between rollouts (after an update, before the next collection), so a checkpoint holds
exactly the steps its model learnt from. A stop request (SIGTERM, SIGINT, the wall-time limit) lets the
rollout under way finish and learn, checkpoints, and ends. A resumed run restores the model, normalizer,
random states and curriculum stage, and reseeds its robots from the run's seed and step count. One trainer
at a time writes a run folder (``<run>/.lock``, ``sb3_huri.runner.lock``); the checkpoint before the newest
is kept in ``<run>/.previous/``, to go on from when the newest is damaged (``sb3_huri.runner.fallback``).
"""

from __future__ import annotations

import signal
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml

from sb3_huri.huri.methods import DEFAULT_METHOD
from sb3_huri.runner.build import preset_env, preset_model, resume_overrides
from sb3_huri.runner.checkpoint import RunCheckpoint
from sb3_huri.runner.fallback import recover
from sb3_huri.runner.lock import hold_run
from sb3_huri.runner.state import RunState, restore_random_states, start_on_levels
from zerith_gym import ZERITH1_ID, robot_of


@dataclass(frozen=True)
class RobustnessSchedule:
    """A robustness row (``sb3_huri.runner.robustness``) each time training passes a multiple of
    `every` steps: `episodes` robots per case, seeded `seed + i`."""

    every: int = 5_000_000
    episodes: int = 50
    seed: int = 1000
    episode_steps: int | None = None
    """Episode length of the evaluation (default: the env's 20 s, as the paper's tests)."""


@dataclass
class TrainingOptions:
    """How a run trains (not what it learns: that is the preset's)."""

    checkpoint_freq: int = 1_000_000
    """Env steps between checkpoints (taken at the first rollout boundary past each)."""
    keep_every: int | None = None
    """Env steps between kept copies of the checkpoint in ``checkpoints/`` (None: none kept)."""
    robustness: RobustnessSchedule | None = None
    max_wall_s: float | None = None
    """Stop (with a checkpoint) after this many seconds of this session."""
    device: str = "auto"
    workers: int | None = None
    """Worker processes stepping robots (same results for any number; None: one per core but one)."""
    physics_threads: int = 1
    threads: int = 1
    tensorboard_log: str | None = None
    verbose: int = 1
    stop_on_signals: bool = True
    """SIGTERM and SIGINT end training after the rollout under way, with a checkpoint (from the main thread
    only). False leaves the process's own handling: the experiment grid's pool processes must die with
    their command, whose death reaches them as a SIGTERM."""


@dataclass
class RunRequest:
    """What to train: a run folder, and for a new run its preset, method and seed."""

    run: Path
    preset: dict[str, Any] | None = None
    """Hyperparameters (RL Zoo preset); None: a resumed run's own ``config.yml``."""
    method: str | None = None
    seed: int | None = None
    hyperparams: dict[str, Any] = field(default_factory=dict)
    """Preset entries replaced, as ``rl_zoo3 train -params``; a resumed model is loaded with them."""
    more_steps: int | None = None
    """Train this many more steps (default: up to ``until``, else the rest of the preset's budget)."""
    until: int | None = None
    """Train until the run holds at least this many steps."""
    curriculum: tuple[int, int] | None = None
    """(steps, stages) of a `RandomizationCurriculum` replacing the preset's."""
    env_id: str = ZERITH1_ID
    """The env the run trains on (``Zerith1-v0``, ``Go2Like-v0``): the name of its files in the folder."""

    def is_resume(self) -> bool:
        return (self.run / f"{self.env_id}.zip").is_file()


def _resolve_preset(request: RunRequest) -> tuple[dict[str, Any], dict[str, Any], str, int]:
    """The preset to train with, the hyperparameters a resumed model changes, the method and the seed."""
    if not request.is_resume():
        if request.preset is None:
            raise ValueError(f"{request.run} holds no {request.env_id}.zip to resume, and no preset given")
        preset = {**request.preset, **request.hyperparams}
        return preset, {}, request.method or DEFAULT_METHOD, 0 if request.seed is None else request.seed
    saved_folder = request.run / request.env_id
    saved = yaml.safe_load((saved_folder / "config.yml").read_text())
    saved_args = yaml.safe_load((saved_folder / "args.yml").read_text())
    method, seed = saved_args["algo"], saved_args["seed"]
    if saved_args.get("env", request.env_id) != request.env_id:
        raise ValueError(f"{request.run} is a run on {saved_args['env']}, not {request.env_id}")
    if request.method is not None and request.method != method:
        raise ValueError(f"{request.run} is a run of {method}, not {request.method}")
    if request.seed is not None and request.seed != seed:
        raise ValueError(f"{request.run} is a run of seed {seed}, not {request.seed}")
    preset = {**(request.preset if request.preset is not None else saved), **request.hyperparams}
    return preset, resume_overrides(saved, preset), method, seed


def _budget(request: RunRequest, preset: dict[str, Any], steps_done: int) -> int:
    """Steps still to train in this call."""
    if request.more_steps is not None:
        return request.more_steps
    until = request.until if request.until is not None else int(preset["n_timesteps"])
    return max(until - steps_done, 0)


def _callbacks(preset: dict[str, Any], request: RunRequest, stage: int | None) -> tuple[list[Any], Any]:
    """The preset's `callback:` entries (RL Zoo's reading), the curriculum replaced if asked, resumed at
    `stage`; and the curriculum (or None)."""
    from rl_zoo3.utils import get_callback_list

    from zerith_gym.sb3.callbacks import RandomizationCurriculum

    callbacks = get_callback_list(preset)
    if request.curriculum is not None:
        callbacks = [c for c in callbacks if not isinstance(c, RandomizationCurriculum)]
        callbacks.append(RandomizationCurriculum(*request.curriculum))
    curriculum = next((c for c in callbacks if isinstance(c, RandomizationCurriculum)), None)
    if curriculum is not None and stage is not None:
        if not 0 <= stage <= curriculum.stages:
            raise ValueError(f"the run reached curriculum stage {stage}, beyond {curriculum.stages}")
        curriculum.start_stage = stage
    return callbacks, curriculum


def _build_model(
    request: RunRequest, preset: dict[str, Any], overrides: dict[str, Any], method: str, seed: int, env: Any,
    options: TrainingOptions,
) -> Any:  # fmt: skip
    """A new model of the preset, or the run's newest checkpoint loaded with `overrides`, on `env`."""
    from sb3_huri import HuRiPPO

    if not request.is_resume():
        return preset_model(
            preset, env, method=method, seed=seed, device=options.device,
            tensorboard_log=options.tensorboard_log, verbose=options.verbose,
        )  # fmt: skip
    if overrides and options.verbose:
        print(f"resuming with changed hyperparameters: {overrides}")
    model = HuRiPPO.load(
        request.run / f"{request.env_id}.zip", env, device=options.device,
        tensorboard_log=options.tensorboard_log, **overrides,
    )  # fmt: skip
    restore_random_states(request.run, request.env_id)
    state = RunState.read(request.run, request.env_id)
    if state.timesteps != model.num_timesteps:
        print(f"warning: {request.run}: a model of {model.num_timesteps} steps, a state of {state.timesteps}")
    if state.terrain_levels is not None:  # the terrain curriculum goes on from where its robots were
        start_on_levels(env, state.terrain_levels)
    env.seed(seed + model.num_timesteps)  # reproducible from this checkpoint ...
    model._last_obs = None  # ... from a reset: SB3 would go on from the observation saved with the model
    return model


def train_run(request: RunRequest, options: TrainingOptions | None = None) -> int:
    """Train the run of `request` (new or resumed) and return the steps its newest checkpoint holds.

    The run folder is held (``sb3_huri.runner.lock.hold_run``) for the whole training: a second trainer
    of it is refused (``RunBusy``, a RunError naming the holder's pid) before anything is written. A resumed
    run whose newest checkpoint is damaged goes on from its previous one (``sb3_huri.runner.fallback``).
    ValueError for a request that cannot be met (no preset for a new run, another method or seed than the
    run's, hyperparameters that would change a resumed run's networks), before anything is written.
    """
    options = options or TrainingOptions()
    if request.preset is None and not request.is_resume():
        raise ValueError(f"{request.run} holds no {request.env_id}.zip to resume, and no preset given")
    with hold_run(request.run):
        recover(request.run, request.env_id, echo=lambda line: print(line, flush=True))
        return _train(request, options)


def _train(request: RunRequest, options: TrainingOptions) -> int:
    """`train_run`'s training, in the folder it holds."""
    import torch as th
    from stable_baselines3.common.callbacks import CallbackList

    from zerith_gym.core.scenarios import get_scenario
    from zerith_gym.robots import locomotion_task

    th.set_num_threads(options.threads)
    preset, overrides, method, seed = _resolve_preset(request)
    resume = request.is_resume()
    state = RunState.read(request.run, request.env_id) if resume else RunState()
    callbacks, curriculum = _callbacks(preset, request, state.curriculum_stage)
    env_kwargs = dict(preset.get("env_kwargs") or {})
    robot = robot_of(request.env_id)
    scenario = get_scenario(env_kwargs.pop("scenario", locomotion_task(robot).default_scenario))
    normalizer = request.run / request.env_id / "vecnormalize.pkl" if resume else None
    env = preset_env(
        preset, seed=seed, normalizer=normalizer, scenario=scenario, workers=options.workers,
        physics_threads=options.physics_threads, robot=robot,
    )  # fmt: skip
    try:
        model = _build_model(request, preset, overrides, method, seed, env, options)
        run_args = {
            "algo": method,
            "env": request.env_id,
            "seed": seed,
            "env_kwargs": {**env_kwargs, "scenario": scenario.name},
        }
        checkpoint = RunCheckpoint(
            request.run, preset, run_args, options.checkpoint_freq, curriculum, options.max_wall_s,
            keep_every=options.keep_every, robustness=options.robustness, verbose=options.verbose,
            env_id=request.env_id,
        )  # fmt: skip
        handlers = _on_stop_signals(checkpoint.request_stop) if options.stop_on_signals else {}
        try:
            if options.verbose:
                print(f"Training {request.run}: {method}, seed {seed}, from {model.num_timesteps} steps")
            began = time.time()
            budget = _budget(request, preset, model.num_timesteps)
            if budget > 0:
                model.learn(
                    budget, callback=CallbackList([*callbacks, checkpoint]), reset_num_timesteps=not resume
                )
            if options.verbose:
                print(f"{checkpoint.saved_steps} steps in {time.time() - began:.0f} s; saved {request.run}")
        finally:
            for stop, handler in handlers.items():
                signal.signal(stop, handler)
        return checkpoint.saved_steps if budget > 0 else model.num_timesteps
    finally:
        env.close()


_STOPS = (signal.SIGTERM, signal.SIGINT)
"""`kill` or Ctrl-C: stop at the end of the rollout under way, with a checkpoint."""


def _on_stop_signals(request_stop: Any) -> dict[int, Any]:
    """Route `_STOPS` to `request_stop` (from the main thread only: elsewhere, nothing); returns the
    handlers replaced."""
    if threading.current_thread() is not threading.main_thread():
        return {}
    return {stop: signal.signal(stop, lambda *_: request_stop()) for stop in _STOPS}
