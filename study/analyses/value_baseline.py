"""How good a baseline each agent's value is, and where its risk level sits before a fall.

PPO's advantages are ``return - baseline``; HuRi's baseline is the distorted value ``V_beta``, and
``V_beta - V_0`` is about ``-beta(s) x spread(s)``, which moves from state to state with the risk level. A
baseline that explains less of the return adds variance to the actor's learning signal. And a critic whose
distribution narrows before a fall reads those states as safe (a low IQR: a risk-seeking level), just where
an averse one was meant. ``measure_value_baseline`` measures both on the agent's own training rollouts:

1. It rebuilds the run's training env and collects rollouts with the algorithm's own loop, as
   ``analyses.advantages`` does (the checkpoint's normalizer frozen, the curriculum held at the
   checkpoint's stage, robot i seeded ``seed + i``, stochastic actions): ``warmup`` rollouts of about one
   episode, then ``rollouts`` measured ones, consecutive in time.
2. For each value it computes the lambda = 1 return of every state of the measured rollouts (the
   discounted rewards to the rollout's end, bootstrapped there and at time-outs from that same value, i.e.
   GAE at lambda = 1 plus the value) and the explained variance ``1 - Var(G - V) / Var(G)`` (SB3's
   ``explained_variance``) of those returns by the value: ``value``, what the agent's advantages use
   (``V_beta``, or PPO's ``V``), and for a quantile critic ``atom_mean``, the plain mean of its atoms
   (``V_0``). Pooled over the measured rollouts, and per rollout.
3. The agent's mean risk level over the states within ``PRE_FALL_STEPS`` steps of a fall (the fall's step
   included; an episode cut by its time limit is no fall) and over every other state (None for PPO, which
   has no risk level).

The results go to ``<run>/evaluations/<steps>-value_baseline.json``; ``study.scripts.value_baseline`` is the
command line, the campaign measures every evaluated agent, and the results page shows them.
"""

from __future__ import annotations

import math
import time
from pathlib import Path
from typing import Any

import numpy as np
import torch as th
from stable_baselines3.common.callbacks import BaseCallback
from stable_baselines3.common.utils import explained_variance, obs_as_tensor

from sb3_huri.experiments.errors import ExperimentError
from sb3_huri.runner.files import read_json, write_json
from sb3_huri.runner.record import EVALUATIONS
from study.analyses.advantages import curriculum_record, hold_stage, training_env
from study.analyses.force_magnitude import checkpoint_files
from study.analyses.risk_levels import band_of, run_env_id

VALUE_BASELINE_SUFFIX = "-value_baseline.json"
"""A checkpoint's value-baseline measures: its run's ``evaluations/<steps>-value_baseline.json``."""
DEFAULT_SEED = 2000
DEFAULT_ROLLOUTS = 6
PRE_FALL_STEPS = 25
"""States this close to a fall (in control steps, the fall's own included) count as before it."""
VALUES = ("value", "atom_mean")
"""The values whose explained variance is measured: the one the advantages use, and the atoms' mean."""


def value_baseline_path(run: Path, steps: int) -> Path:
    """Where the value-baseline measures of the checkpoint at ``steps`` go."""
    return Path(run) / EVALUATIONS / f"{steps}{VALUE_BASELINE_SUFFIX}"


def lambda_one_returns(
    rewards: np.ndarray,
    episode_starts: np.ndarray,
    last_values: np.ndarray,
    last_dones: np.ndarray,
    gamma: float,
) -> np.ndarray:
    """The discounted return of every state of a rollout ``(T, E)`` to its end, bootstrapped there from
    ``last_values`` unless ``last_dones``. ``rewards`` already hold ``gamma x`` the value of a time-out's
    final state at its step, as the algorithm's buffer adds it."""
    returns = np.zeros_like(rewards, dtype=np.float64)
    following = np.asarray(last_values, dtype=np.float64)
    for t in reversed(range(len(rewards))):
        ended = last_dones if t == len(rewards) - 1 else episode_starts[t + 1]
        following = rewards[t] + gamma * (1.0 - ended) * following
        returns[t] = following
    return returns


def steps_to_fall(dones: np.ndarray, falls: np.ndarray) -> np.ndarray:
    """For every step ``(T, E)``, how many steps remain until its episode ends in a fall within the array
    (0 at the fall's own step); infinite where the episode ends otherwise or not within it."""
    remaining = np.full(dones.shape, np.inf)
    countdown = np.full(dones.shape[1], np.inf)
    for t in reversed(range(len(dones))):
        countdown = np.where(dones[t], np.where(falls[t], 0.0, np.inf), countdown + 1.0)
        remaining[t] = countdown
    return remaining


class EpisodeEnds(BaseCallback):
    """Records, step by step, which robots' episodes ended and which of those ends were time-outs."""

    def __init__(self) -> None:
        super().__init__()
        self.dones: list[np.ndarray] = []
        self.time_outs: list[np.ndarray] = []

    def _on_step(self) -> bool:
        dones, infos = self.locals["dones"], self.locals["infos"]
        self.dones.append(np.asarray(dones, dtype=bool).copy())
        self.time_outs.append(np.array([bool(info.get("TimeLimit.truncated", False)) for info in infos]))
        return True

    def take(self) -> tuple[np.ndarray, np.ndarray]:
        """The steps recorded since the last take: (dones, falls), each ``(T, E)``."""
        dones, time_outs = np.array(self.dones, dtype=bool), np.array(self.time_outs, dtype=bool)
        self.dones, self.time_outs = [], []
        return dones, dones & ~time_outs


def _values(model: Any, last_atoms: np.ndarray) -> dict[str, tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """Per value of ``VALUES`` the model has: (its value per state, its last states', its time-out
    bootstraps), from the rollout just collected."""
    buffer = model.rollout_buffer
    values = {
        "value": (
            buffer.values,
            np.einsum("en,en->e", last_atoms, buffer.last_weights),
            buffer.bootstrap_values,
        )
    }
    if model.risk_model.distributional:
        values["atom_mean"] = (
            buffer.atoms.mean(axis=-1),
            last_atoms.mean(axis=-1),
            buffer.bootstrap_atoms.mean(axis=-1),
        )
    return values


def _rollout(model: Any, env: Any, callback: Any) -> dict[str, Any]:
    """Collect one rollout; each value's (value, return) per state and the rollout's risk levels."""
    if not model.collect_rollouts(env, callback, model.rollout_buffer, model.n_steps):
        raise ExperimentError("a callback stopped the rollout; nothing to measure")
    with th.no_grad():
        outputs = model.policy.predict_values(obs_as_tensor(model._last_obs, model.device))
    last_atoms = th.sort(outputs, dim=-1).values.cpu().numpy()
    buffer, dones = model.rollout_buffer, model._last_episode_starts.astype(np.float64)
    pairs = {}
    for name, (values, last, bootstrap) in _values(model, last_atoms).items():
        rewards = buffer.rewards + buffer.gamma * bootstrap
        returns = lambda_one_returns(rewards, buffer.episode_starts, last, dones, buffer.gamma)
        pairs[name] = (np.asarray(values, dtype=np.float64), returns)
    return {"pairs": pairs, "risk": buffer.risk.copy()}


def _explained(pairs: list[tuple[np.ndarray, np.ndarray]]) -> float:
    values = np.concatenate([v.ravel() for v, _ in pairs])
    returns = np.concatenate([g.ravel() for _, g in pairs])
    return float(explained_variance(values, returns))


def measure_value_baseline(
    run: Path,
    *,
    steps: int | None = None,
    seed: int = DEFAULT_SEED,
    warmup: int | None = None,
    rollouts: int = DEFAULT_ROLLOUTS,
) -> Path:
    """Measure the agent of ``run`` (module docstring) and write its file; return the file's path.

    ``steps``: the checkpoint (default: its newest final evaluation's, else its newest model), from the
    run, a kept checkpoint or the commit that holds it (``force_magnitude.checkpoint_files``). ``warmup``:
    rollouts collected first (default: as many as one episode takes); ``rollouts``: measured.
    """
    from stable_baselines3.common.logger import configure

    from sb3_huri.runner.folder import load_checkpoint

    if (warmup is not None and warmup < 0) or rollouts < 1:
        raise ValueError(f"warmup must be >= 0 and rollouts >= 1, got {warmup} and {rollouts}")
    run = Path(run)
    env_id = run_env_id(run)
    if steps is None:
        evaluated = sorted(int(p.stem) for p in (run / EVALUATIONS).glob("*.json") if p.stem.isdigit())
        steps = (
            evaluated[-1]
            if evaluated
            else int(read_json(run / env_id / "state.json", "a state")["timesteps"])
        )
    began = time.time()
    with checkpoint_files(run, steps, env_id) as (measured_steps, model_file, normalizer_file, source):
        model, normalizer = load_checkpoint(model_file, normalizer_file)
        newest = source == f"{env_id}.zip"
        env, randomization, terrain, episode_steps = training_env(run, env_id, normalizer, seed, newest)
    if model.num_timesteps != measured_steps:
        raise ExperimentError(f"{run} saved a new checkpoint while it was read; measure it again")
    warmup = math.ceil(episode_steps / model.n_steps) if warmup is None else warmup
    ends = EpisodeEnds()
    try:
        model.set_env(env)
        model.set_logger(configure(None, []))
        callback = hold_stage(model, randomization, [*terrain, ends])
        model._last_obs, model._last_episode_starts = env.reset(), np.ones(env.num_envs, dtype=bool)
        th.manual_seed(seed)
        for _ in range(warmup):
            _rollout(model, env, callback)
        ends.take()
        collected = [_rollout(model, env, callback) for _ in range(rollouts)]
        dones, falls = ends.take()
    finally:
        env.close()
    record = {
        "env_id": env_id,
        "method": getattr(model, "method", None),
        "steps": measured_steps,
        "model": source,
        "band": band_of(model),
        "curriculum": curriculum_record(randomization),
        "settings": {
            "seed": seed,
            "warmup": warmup,
            "rollouts": rollouts,
            "robots": model.n_envs,
            "rollout_steps": model.n_steps,
            "pre_fall_steps": PRE_FALL_STEPS,
        },
        "eval_s": time.time() - began,
        **_measures(collected, dones, falls, model.risk_model.distributional),
    }
    path = value_baseline_path(run, measured_steps)
    path.parent.mkdir(parents=True, exist_ok=True)
    write_json(path, record)
    print(f"{run}: {measured_steps:,} steps ({source}), {record['eval_s']:.0f} s")
    return path


def _measures(
    collected: list[dict[str, Any]], dones: np.ndarray, falls: np.ndarray, distributional: bool
) -> dict[str, Any]:
    """The file's measures from the measured rollouts (consecutive in time) and their episode ends."""
    names = [name for name in VALUES if name in collected[0]["pairs"]]
    explained = {name: _explained([c["pairs"][name] for c in collected]) for name in names}
    per_rollout = [{name: _explained([c["pairs"][name]]) for name in names} for c in collected]
    before = steps_to_fall(dones, falls) < PRE_FALL_STEPS
    risk = np.concatenate([c["risk"] for c in collected]).astype(np.float64)
    fall_risk = {"falls": int(falls.sum()), "before_fall_states": int(before.sum())}
    for key, where in (("risk_before_fall", before), ("risk_elsewhere", ~before)):
        fall_risk[key] = float(risk[where].mean()) if distributional and where.any() else None
    return {"explained_variance": explained, "per_rollout": per_rollout, **fall_risk}


def measured_record(path: Path) -> dict[str, Any] | None:
    """The measures at ``path`` if the file holds them all (None for no file or an incomplete one)."""
    if not path.is_file():
        return None
    record = read_json(path, "an agent's value-baseline measures")
    keys = ("explained_variance", "per_rollout", "falls", "risk_before_fall", "risk_elsewhere")
    complete = isinstance(record, dict) and all(key in record for key in keys)
    return record if complete and "value" in record["explained_variance"] else None


def value_baseline_text(path: Path) -> str:
    """A value-baseline file as text: what was measured, the explained variances, the risk before falls."""
    record = read_json(path, "an agent's value-baseline measures")
    settings = record["settings"]
    robots, length = settings["robots"], settings["rollout_steps"]
    lines = [
        f"{path}: {record['method']} at {record['steps']:,} steps ({record['model']}), "
        f"{settings['rollouts']} rollouts of {robots} robots x {length} steps "
        f"after {settings['warmup']} (seed {settings['seed']}), {record['eval_s']:.0f} s",
    ]
    for name, explained in record["explained_variance"].items():
        spread = [rollout[name] for rollout in record["per_rollout"]]
        lines.append(
            f"explained variance of the lambda = 1 returns by {name}: {explained:.3f} "
            f"(rollouts {min(spread):.3f} to {max(spread):.3f})"
        )
    if record["risk_before_fall"] is not None:
        falls, states = record["falls"], record["before_fall_states"]
        lines.append(
            f"risk level within {settings['pre_fall_steps']} steps of a fall: "
            f"{record['risk_before_fall']:+.3f} ({states} states, {falls} falls); "
            f"elsewhere {record['risk_elsewhere']:+.3f}"
        )
    return "\n".join(lines)
