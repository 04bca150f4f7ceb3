"""How much a HuRi agent's risk distortion moves the advantages its actor learns from.

PPO's actor follows the advantages; HuRi's differ from PPO's only through the distorted value ``V_beta`` that
GAE bootstraps from (docs/huri.md, "The algorithm"). A risk level that barely changes what the actor learns
is no risk-awareness at all, whatever its statistics; and a risk level that is the same on every state is a
fixed distortion, not an adaptive one. ``measure_advantages`` measures both on the agent's own training
rollouts:

1. It rebuilds the run's training env (its preset's env in this process, the checkpoint's normalizer with
   its statistics frozen, its curricula) and collects rollouts with the algorithm's own loop
   (``HuRiPPO.collect_rollouts``: stochastic actions, each state's risk level, GAE on ``V_beta``; the RND
   predictor fitted after each rollout and the percentile band moved, as in training), robot i seeded
   ``seed + i``. The randomization curriculum's stage is held where the checkpoint left it: the run's saved
   stage for its newest model, the schedule's for a kept checkpoint (whose terrain levels are not saved: a
   run on tile terrains is measured at its newest model only, its robots moving between levels as in
   training). All robots start at a
   reset, so ``warmup`` rollouts of about one episode come first; then ``rollouts`` measured ones, about
   one episode too, so that every phase of an episode is in them.
2. For each measured rollout it computes the advantages again from the same atoms, rewards and episode ends
   under one risk level for every state (``constant_risk_advantages``): the neutral one (Wang ``beta = 0``,
   CVaR ``alpha = 1``: the critic's mean, what a risk-free HuRi would use) and the rollout's mean risk
   level (the same distortion with the per-state adaptation removed); and under the same per-state levels
   read the other way (``other_td_level``, ``sb3_huri.common.risk_gae``): each TD error at the level of the
   state its step starts from for an agent that trained on each value at its own state's level, and the
   reverse for one that trained on the former.
3. Against each: the Pearson correlation of the agent's advantages with them (dominated by the largest
   advantages), the share of samples whose advantage changes sign (dominated by the many small ones) and
   that share weighted by the size of the agent's advantage (how much of the signal turns around). The
   other reading is also held against the neutral level (``other_td_level["neutral"]``): how far an agent
   reading its levels that way would move the signal on the same states.

The results go to ``<run>/evaluations/<steps>-advantages.json``; ``study.scripts.advantages`` is the command
line, the campaign measures every evaluated agent with a quantile critic, and the results page shows them.
"""

from __future__ import annotations

import math
import time
from pathlib import Path
from typing import Any

import numpy as np
import torch as th

from sb3_huri.common.distortion import distortion_weights
from sb3_huri.experiments.errors import ExperimentError
from sb3_huri.runner.files import read_json, write_json
from sb3_huri.runner.record import EVALUATIONS
from study.analyses.risk_levels import band_of, choose_checkpoint, load_measured, run_env_id

ADVANTAGES_SUFFIX = "-advantages.json"
"""A checkpoint's advantage measures are in its run's ``evaluations/`` folder, ``<steps>-advantages.json``."""
DEFAULT_SEED = 2000
COMPARATORS = ("neutral", "constant", "other_td_level")
"""What the agent's advantages are held against: the neutral risk level, the rollout's mean level (both one
level for every state), and the per-state levels under the other reading of a TD error's levels."""
SHOWN_WITHOUT = ("other_td_level",)
"""Comparators a file may lack and still be shown (``measured_record(..., shown=True)``): those added after
files were written for checkpoints that no run holds any more, which cannot be measured again."""
COMPARATOR_TEXT = {
    "neutral": "the neutral level",
    "constant": "the rollout's mean level",
    "other_td_level": "its levels read per {reading}",
}
"""Each comparator in words (``{reading}``: the other TD reading, ``state`` or ``step``)."""
MEASURES = ("correlation", "sign_changes", "weighted_sign_changes")
"""What ``signal_change`` gives for each comparator."""


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
    """How far advantages ``own`` are from ``other`` (same samples): their correlation, the share of samples
    whose sign differs, and that share weighted by ``|own|``."""
    own, other = np.ravel(own).astype(np.float64), np.ravel(other).astype(np.float64)
    if own.std() == 0.0 or other.std() == 0.0:
        raise ExperimentError("a rollout's advantages are all equal: no learning signal to compare")
    turned = np.sign(own) != np.sign(other)
    return {
        "correlation": float(np.corrcoef(own, other)[0, 1]),
        "sign_changes": float(turned.mean()),
        "weighted_sign_changes": float(np.abs(own)[turned].sum() / np.abs(own).sum()),
    }


def rollout_measures(model: Any, last_atoms: np.ndarray, dones: np.ndarray) -> dict[str, Any]:
    """The measures of the rollout just collected (module docstring, items 2-3): its risk levels, and its
    advantages against the neutral and the constant mean risk level and under the other TD reading."""
    buffer = model.rollout_buffer
    own, risk = buffer.advantages.copy(), buffer.risk.copy()
    other_reading = "step" if buffer.td_level == "state" else "state"
    measures: dict[str, Any] = {"risk_mean": float(risk.mean()), "risk_sd": float(risk.std())}
    other_td = buffer.advantages_under(other_reading)  # before the constant levels overwrite the buffer's
    measures["other_td_level"] = {"level": other_reading, **signal_change(own, other_td)}
    levels = {"neutral": neutral_level(model.risk_model.distortion), "constant": float(risk.mean())}
    for name, level in levels.items():
        other = constant_risk_advantages(model, last_atoms, dones, level)
        measures[name] = {"level": level, **signal_change(own, other)}
        if name == "neutral":
            measures["other_td_level"]["neutral"] = signal_change(other_td, other)
    return measures


def training_env(
    run: Path, env_id: str, normalizer: Any, seed: int, newest: bool
) -> tuple[Any, Any, list[Any], int]:
    """The run's training env in this process with the checkpoint's ``normalizer`` (its statistics frozen),
    the preset's randomization curriculum (None without one; the run's saved stage for its ``newest`` model,
    the schedule's for a kept checkpoint) and its other curricula (the saved terrain levels), and the
    preset's episode length."""
    import yaml
    from rl_zoo3.utils import get_callback_list
    from stable_baselines3.common.vec_env import VecNormalize

    from sb3_huri.runner.build import preset_env
    from sb3_huri.runner.state import RunState, start_on_levels
    from zerith_gym import robot_of
    from zerith_gym.core.task import EPISODE_STEPS
    from zerith_gym.sb3.callbacks import RandomizationCurriculum, TerrainCurriculum

    config = yaml.safe_load((run / env_id / "config.yml").read_text())
    preset = dict(config) if isinstance(config, list) else config  # RL Zoo writes a list of pairs
    callbacks = get_callback_list(preset)
    randomization = next((c for c in callbacks if isinstance(c, RandomizationCurriculum)), None)
    terrain = [c for c in callbacks if isinstance(c, TerrainCurriculum)]
    if terrain and not newest:
        raise ExperimentError(
            f"{run}: a kept checkpoint's terrain levels are not saved; measure the run's newest model"
        )
    env = preset_env(preset, seed=seed, workers=0, robot=robot_of(env_id))
    if normalizer is not None:
        normalizer.set_venv(env.venv if isinstance(env, VecNormalize) else env)
        normalizer.training, env = False, normalizer  # the checkpoint's statistics, as it left them
    state = RunState.read(run, env_id)
    if newest and randomization is not None:
        randomization.start_stage = state.curriculum_stage
    if newest and state.terrain_levels is not None:
        start_on_levels(env, state.terrain_levels)
    episode_steps = int((preset.get("env_kwargs") or {}).get("episode_steps", EPISODE_STEPS))
    return env, randomization, terrain, episode_steps


def measure_advantages(
    run: Path,
    *,
    steps: int | None = None,
    seed: int = DEFAULT_SEED,
    warmup: int | None = None,
    rollouts: int | None = None,
) -> Path:
    """Measure the agent of ``run`` (module docstring) and write its file; return the file's path.

    ``steps``: the checkpoint (``risk_levels.choose_checkpoint``: by default its final evaluation's if the
    run holds it, else its newest model). ``warmup``, ``rollouts``: rollouts collected first and measured
    (default: each as many as one episode takes, at least two measured). ExperimentError for a model
    without a quantile critic, a run that saved a new checkpoint while it was read, or a kept checkpoint of
    a run on tile terrains.
    """
    from stable_baselines3.common.logger import configure

    if (warmup is not None and warmup < 0) or (rollouts is not None and rollouts < 1):
        raise ValueError(f"warmup must be >= 0 and rollouts >= 1, got {warmup} and {rollouts}")
    run = Path(run)
    env_id = run_env_id(run)
    steps, model_file, normalizer_file, why = choose_checkpoint(run, env_id, steps)
    model, normalizer = load_measured(run, env_id, steps, model_file, normalizer_file)
    if not getattr(model, "risk_model", None) or not model.risk_model.distributional:
        raise ExperimentError(f"{run}: its model has no quantile critic, hence no risk distortion to measure")
    began, band = time.time(), band_of(model)
    newest = model_file == run / f"{env_id}.zip"
    env, randomization, terrain, episode_steps = training_env(run, env_id, normalizer, seed, newest)
    per_episode = math.ceil(episode_steps / model.n_steps)
    warmup = per_episode if warmup is None else warmup
    rollouts = max(per_episode, 2) if rollouts is None else rollouts
    try:
        model.set_env(env)
        model.set_logger(configure(None, []))
        callback = hold_stage(model, randomization, terrain)
        model._last_obs, model._last_episode_starts = env.reset(), np.ones(env.num_envs, dtype=bool)
        th.manual_seed(seed)
        measured = [
            _rollout(model, env, callback, measure=index >= warmup) for index in range(warmup + rollouts)
        ]
    finally:
        env.close()
    record = {
        "env_id": env_id,
        "method": getattr(model, "method", None),
        "steps": steps,
        "model": str(model_file.relative_to(run)) if model_file.is_relative_to(run) else str(model_file),
        "band": band,
        "curriculum": curriculum_record(randomization),
        "settings": {
            "seed": seed,
            "warmup": warmup,
            "rollouts": rollouts,
            "robots": model.n_envs,
            "rollout_steps": model.n_steps,
        },
        "eval_s": time.time() - began,
        "rollouts": [m for m in measured if m is not None],
    }
    path = advantages_path(run, steps)
    path.parent.mkdir(parents=True, exist_ok=True)
    write_json(path, record)
    print(f"{run}: {steps:,} steps ({why}), {record['eval_s']:.0f} s")
    return path


def curriculum_record(randomization: Any) -> dict[str, Any] | None:
    """The stage the rollouts were collected at, as a measure's file records it (None without a
    randomization curriculum)."""
    if randomization is None:
        return None
    return {"stage": randomization.stage, "stages": randomization.stages, "scale": randomization.scale}


def hold_stage(model: Any, randomization: Any, others: list[Any]) -> Any:
    """Set the randomization curriculum's stage once (its callback then leaves the rollouts: the stage is the
    checkpoint's throughout), and return the callback the rollouts run: the ``others`` (the terrain's
    levels move as in training) behind the algorithm's own (the RND predictor's fit first)."""
    if randomization is not None:
        randomization.init_callback(model)
        randomization.on_training_start(locals(), globals())
        randomization.on_rollout_start()
    callback = model._init_callback(others)
    callback.on_training_start(locals(), globals())
    return callback


def _rollout(model: Any, env: Any, callback: Any, measure: bool) -> dict[str, Any] | None:
    """Collect one rollout into the model's buffer; its measures if ``measure``."""
    from stable_baselines3.common.utils import obs_as_tensor

    if not model.collect_rollouts(env, callback, model.rollout_buffer, model.n_steps):
        raise ExperimentError("a callback stopped the rollout; nothing to measure")
    if not measure:
        return None
    with th.no_grad():
        outputs = model.policy.predict_values(obs_as_tensor(model._last_obs, model.device))
    last_atoms = th.sort(outputs, dim=-1).values.cpu().numpy()
    return rollout_measures(model, last_atoms, model._last_episode_starts)


def measured_record(path: Path, shown: bool = False) -> dict[str, Any] | None:
    """The advantage measures at ``path`` if the file holds every measure of every comparator for each of
    its rollouts (None for no file, or one written before a measure was added: to be measured again).
    ``shown``: a file that lacks only comparators of ``SHOWN_WITHOUT`` will do (the results page shows what
    it holds)."""
    if not path.is_file():
        return None
    record = read_json(path, "an agent's advantage measures")
    rollouts = record.get("rollouts") if isinstance(record, dict) else None
    wanted = [name for name in COMPARATORS if not (shown and name in SHOWN_WITHOUT)]
    complete = bool(rollouts) and all(
        key in rollout.get(name, {}) for rollout in rollouts for name in wanted for key in MEASURES
    )
    if complete and "other_td_level" in wanted:  # and the other reading against the neutral level
        complete = all(key in r["other_td_level"].get("neutral", {}) for r in rollouts for key in MEASURES)
    return record if complete and "curriculum" in record else None


def summary(record: dict[str, Any]) -> dict[str, Any]:
    """The measured rollouts' means (risk level and its spread over states, each comparator's measures) and
    each measure's range over the rollouts (``<name>_range``); a comparator the file lacks is left out."""
    rollouts = record["rollouts"]
    means = {key: float(np.mean([r[key] for r in rollouts])) for key in ("risk_mean", "risk_sd")}
    for name in (name for name in COMPARATORS if name in rollouts[0]):
        for key in MEASURES:
            values = [r[name][key] for r in rollouts]
            means[f"{name}_{key}"] = float(np.mean(values))
            means[f"{name}_{key}_range"] = (float(np.min(values)), float(np.max(values)))
    if "neutral" in rollouts[0].get("other_td_level", {}):
        for key in MEASURES:
            values = [r["other_td_level"]["neutral"][key] for r in rollouts]
            means[f"other_td_level_neutral_{key}"] = float(np.mean(values))
            means[f"other_td_level_neutral_{key}_range"] = (float(np.min(values)), float(np.max(values)))
    return means


def advantages_text(path: Path) -> str:
    """An advantage-measures file as text: what was measured, then its means and ranges over the rollouts."""
    record = read_json(path, "an agent's advantage measures")
    means = summary(record)
    settings, curriculum = record["settings"], record.get("curriculum")
    stage = "" if curriculum is None else f", curriculum scale {curriculum['scale']:g}"
    lines = [
        f"{path}: {record['method']} at {record['steps']:,} steps{stage}, {settings['rollouts']} rollouts of "
        f"{settings['robots']} robots x {settings['rollout_steps']} steps after {settings['warmup']} "
        f"(seed {settings['seed']}), {record['eval_s']:.0f} s",
        f"risk level: mean {means['risk_mean']:+.3f}, sd over states {means['risk_sd']:.3f}",
    ]
    reading = record["rollouts"][0].get("other_td_level", {}).get("level")
    for name in (name for name in COMPARATORS if name in record["rollouts"][0]):
        lines.append(f"against {COMPARATOR_TEXT[name].format(reading=reading)}: " + _cells(means, name))
    if "other_td_level_neutral_correlation" in means:
        cells = _cells(means, "other_td_level_neutral")
        lines.append(f"its levels read per {reading}, against the neutral level: {cells}")
    return "\n".join(lines)


def _cells(means: dict[str, Any], prefix: str) -> str:
    """The measures of ``summary``'s keys under ``prefix``, each with its range over the rollouts."""
    cells = []
    for key in MEASURES:
        low, high = means[f"{prefix}_{key}_range"]
        cells.append(f"{key.replace('_', ' ')} {means[f'{prefix}_{key}']:.3f} [{low:.3f}, {high:.3f}]")
    return ", ".join(cells)
