"""How much a HuRi agent's risk distortion moves the advantages its actor learns from.

PPO's actor follows the advantages; HuRi's differ from PPO's only through the distorted value ``V_beta`` that
GAE bootstraps from (docs/huri.md, "The algorithm"). A risk level that barely changes what the actor learns
is no risk-awareness at all, whatever its statistics; and a risk level that is the same on every state is a
fixed distortion, not an adaptive one. ``measure_advantages`` measures both on the agent's own training
rollouts:

1. It rebuilds the run's training env as a resumed run would (its preset's env and callbacks, its
   normalizer, the curriculum stage and terrain levels of its state) and collects rollouts with the
   algorithm's own loop (``HuRiPPO.collect_rollouts``: stochastic actions, each state's risk level, GAE on
   ``V_beta``), ``warmup`` rollouts first so that episodes are under way as in training, then ``rollouts``
   measured ones, robot i seeded ``seed + i``.
2. For each measured rollout it computes the advantages again from the same atoms, rewards and episode ends
   under a constant risk level (``constant_risk_advantages``): the neutral one (Wang ``beta = 0``, CVaR
   ``alpha = 1``: the critic's mean, what a risk-free HuRi would use) and the rollout's mean risk level (the
   same distortion with the per-state adaptation removed).
3. Against each: the Pearson correlation of the agent's advantages with them, the share of samples whose
   advantage changes sign, and the standard deviation of the difference of the two after each is
   standardized over the rollout (the actor normalizes advantages per minibatch: 0 means the same learning
   signal, 1.41 unrelated ones).

The results go to ``<run>/evaluations/<steps>-advantages.json``; ``benchmarks/advantages.py`` is the command
line, the campaign measures every evaluated agent with a quantile critic, and the results page shows them.
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

import numpy as np
import torch as th

from sb3_huri.common.distortion import distortion_weights
from sb3_huri.experiments.analyses.risk_levels import choose_checkpoint, load_measured, run_env_id
from sb3_huri.experiments.errors import ExperimentError
from sb3_huri.runner.files import read_json, write_json
from sb3_huri.runner.record import EVALUATIONS

ADVANTAGES_SUFFIX = "-advantages.json"
"""A checkpoint's advantage measures are in its run's ``evaluations/`` folder, ``<steps>-advantages.json``."""
DEFAULT_SEED = 2000
DEFAULT_WARMUP = 1
DEFAULT_ROLLOUTS = 2
COMPARATORS = ("neutral", "constant")
"""The constant risk levels the agent's advantages are held against: the neutral one, the rollout's mean."""


def advantages_path(run: Path, steps: int) -> Path:
    """Where the advantage measures of the checkpoint at ``steps`` go."""
    return Path(run) / EVALUATIONS / f"{steps}{ADVANTAGES_SUFFIX}"


def neutral_level(distortion: str) -> float:
    """The risk level at which a distortion is the plain mean: Wang's ``beta = 0``, CVaR's ``alpha = 1``."""
    return 0.0 if distortion == "wang" else 1.0


def constant_risk_advantages(
    model: Any, last_atoms: np.ndarray, dones: np.ndarray, level: float
) -> np.ndarray:
    """The advantages of the model's collected rollout (in ``model.rollout_buffer``) had every state's risk
    level been ``level``: GAE by the buffer's own ``compute_returns_and_advantage`` on the same atoms,
    rewards and episode ends (time-outs bootstrapped from their final states' atoms), with the distorted
    value of ``level``. The buffer's risk arrays are restored afterwards; its advantages, returns and targets
    are the constant level's until the buffer is filled again.

    :param last_atoms: sorted atoms of the states after the rollout ``(n_envs, N)``
    :param dones: whether each robot's last step ended its episode
    """
    buffer = model.rollout_buffer
    n_quantiles = buffer.atoms.shape[-1]
    weights = distortion_weights(model.risk_model.distortion, th.tensor(float(level)), n_quantiles).numpy()
    saved = buffer.distortion_weights.copy(), buffer.bootstrap_values.copy()
    buffer.distortion_weights[:] = weights
    buffer.bootstrap_values = (buffer.bootstrap_atoms @ weights).astype(np.float32)
    try:
        last_values = th.as_tensor(last_atoms @ weights, dtype=th.float32)
        buffer.compute_returns_and_advantage(last_values, dones, last_atoms)
    finally:
        buffer.distortion_weights[:], buffer.bootstrap_values = saved
    return buffer.advantages.copy()


def signal_change(own: np.ndarray, other: np.ndarray) -> dict[str, float]:
    """How far advantages ``own`` are from ``other`` (same samples): correlation, share of sign changes, and
    the standard deviation of the difference of the two standardized arrays (``sqrt(2 (1 - corr))``)."""
    own, other = np.ravel(own).astype(np.float64), np.ravel(other).astype(np.float64)
    if own.std() == 0.0 or other.std() == 0.0:
        raise ExperimentError("a rollout's advantages are all equal: no learning signal to compare")
    correlation = float(np.corrcoef(own, other)[0, 1])
    gap = (own - own.mean()) / own.std() - (other - other.mean()) / other.std()
    return {
        "correlation": correlation,
        "sign_changes": float(np.mean(np.sign(own) != np.sign(other))),
        "standardized_gap": float(gap.std()),
    }


def rollout_measures(model: Any, last_atoms: np.ndarray, dones: np.ndarray) -> dict[str, Any]:
    """The measures of the rollout just collected (module docstring, item 2-3): its risk levels, and its
    advantages against the neutral and the constant mean risk level."""
    buffer = model.rollout_buffer
    own, risk = buffer.advantages.copy(), buffer.risk.copy()
    levels = {"neutral": neutral_level(model.risk_model.distortion), "constant": float(risk.mean())}
    measures: dict[str, Any] = {"risk_mean": float(risk.mean()), "risk_sd": float(risk.std())}
    for name, level in levels.items():
        other = constant_risk_advantages(model, last_atoms, dones, level)
        measures[name] = {"level": level, **signal_change(own, other)}
    return measures


def _training_env(run: Path, env_id: str, normalizer_file: Path | None, seed: int) -> tuple[Any, Any]:
    """The run's training env as a resumed run builds it (one process) and its preset's callbacks, at the
    curriculum stage and on the terrain levels of its state (the callbacks not yet bound to a model)."""
    import yaml
    from rl_zoo3.utils import get_callback_list
    from stable_baselines3.common.callbacks import CallbackList

    from sb3_huri.runner.build import preset_env
    from sb3_huri.runner.state import RunState, start_on_levels
    from zerith_gym import robot_of
    from zerith_gym.sb3.callbacks import RandomizationCurriculum

    config = yaml.safe_load((run / env_id / "config.yml").read_text())
    preset = dict(config) if isinstance(config, list) else config  # RL Zoo writes a list of pairs
    state = RunState.read(run, env_id)
    env = preset_env(preset, seed=seed, normalizer=normalizer_file, workers=0, robot=robot_of(env_id))
    if hasattr(env, "training"):
        env.training = False  # the normalizer's statistics stay the checkpoint's
    callbacks = get_callback_list(preset)
    for callback in callbacks:
        if isinstance(callback, RandomizationCurriculum) and state.curriculum_stage is not None:
            callback.start_stage = state.curriculum_stage
    if state.terrain_levels is not None:
        start_on_levels(env, state.terrain_levels)
    return env, CallbackList(callbacks)


def measure_advantages(
    run: Path,
    *,
    steps: int | None = None,
    seed: int = DEFAULT_SEED,
    warmup: int = DEFAULT_WARMUP,
    rollouts: int = DEFAULT_ROLLOUTS,
) -> Path:
    """Measure the agent of ``run`` (module docstring) and write its file; return the file's path.

    ``steps``: the checkpoint (``risk_levels.choose_checkpoint``: by default its final evaluation's if the
    run holds it, else its newest model). ExperimentError for a model without a quantile critic, or a run
    that saved a new checkpoint while it was read.
    """
    from stable_baselines3.common.logger import configure
    from stable_baselines3.common.utils import obs_as_tensor

    if warmup < 0 or rollouts < 1:
        raise ValueError(f"warmup must be >= 0 and rollouts >= 1, got {warmup} and {rollouts}")
    run = Path(run)
    env_id = run_env_id(run)
    steps, model_file, normalizer_file, why = choose_checkpoint(run, env_id, steps)
    model, _ = load_measured(run, env_id, steps, model_file, normalizer_file)
    if not getattr(model, "risk_model", None) or not model.risk_model.distributional:
        raise ExperimentError(f"{run}: its model has no quantile critic, hence no risk distortion to measure")
    began = time.time()
    env, callback = _training_env(run, env_id, normalizer_file, seed)
    try:
        model.set_env(env)
        model.set_logger(configure(None, []))
        model._last_obs, model._last_episode_starts = env.reset(), np.ones(env.num_envs, dtype=bool)
        th.manual_seed(seed)
        callback.init_callback(model)
        callback.on_training_start(locals(), globals())
        measured = []
        for index in range(warmup + rollouts):
            model.collect_rollouts(env, callback, model.rollout_buffer, model.n_steps)
            if index < warmup:
                continue
            with th.no_grad():
                outputs = model.policy.predict_values(obs_as_tensor(model._last_obs, model.device))
            last_atoms = th.sort(outputs, dim=-1).values.cpu().numpy()
            measured.append(rollout_measures(model, last_atoms, model._last_episode_starts))
    finally:
        env.close()
    record = {
        "env_id": env_id,
        "method": getattr(model, "method", None),
        "steps": steps,
        "model": str(model_file.relative_to(run)) if model_file.is_relative_to(run) else str(model_file),
        "curriculum_stage": _stage(run, env_id),
        "settings": {
            "seed": seed,
            "warmup": warmup,
            "rollouts": rollouts,
            "robots": model.n_envs,
            "rollout_steps": model.n_steps,
        },
        "eval_s": time.time() - began,
        "rollouts": measured,
    }
    path = advantages_path(run, steps)
    path.parent.mkdir(parents=True, exist_ok=True)
    write_json(path, record)
    print(f"{run}: {steps:,} steps ({why}), {record['eval_s']:.0f} s")
    return path


def _stage(run: Path, env_id: str) -> int | None:
    from sb3_huri.runner.state import RunState

    return RunState.read(run, env_id).curriculum_stage


def summary(record: dict[str, Any]) -> dict[str, float]:
    """The measured rollouts' means: risk level and its spread, and each comparator's three measures."""
    rollouts = record["rollouts"]
    means = {key: float(np.mean([r[key] for r in rollouts])) for key in ("risk_mean", "risk_sd")}
    for name in COMPARATORS:
        for key in ("correlation", "sign_changes", "standardized_gap"):
            means[f"{name}_{key}"] = float(np.mean([r[name][key] for r in rollouts]))
    return means


def advantages_text(path: Path) -> str:
    """An advantage-measures file as text: what was measured, then its means."""
    record = read_json(path, "an agent's advantage measures")
    means = summary(record)
    settings = record["settings"]
    lines = [
        f"{path}: {record['method']} at {record['steps']:,} steps, {settings['rollouts']} rollouts of "
        f"{settings['robots']} robots x {settings['rollout_steps']} steps after {settings['warmup']} "
        f"(seed {settings['seed']}), {record['eval_s']:.0f} s",
        f"risk level: mean {means['risk_mean']:+.3f}, sd over states {means['risk_sd']:.3f}",
    ]
    for name in COMPARATORS:
        lines.append(
            f"against the {name} level: correlation {means[f'{name}_correlation']:.3f}, sign changes "
            f"{means[f'{name}_sign_changes']:.3f}, standardized gap {means[f'{name}_standardized_gap']:.3f}"
        )
    return "\n".join(lines)
