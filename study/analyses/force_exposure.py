"""How much of a training scenario an agent meets: its robot-steps and falls under each force it names.

A force cycle's later phases act only on robots that outlast its earlier ones, so what a policy trains on
depends on how long it stays up. ``exposure`` runs an agent's stochastic policy (as in training) on a
scenario and counts robot-steps and falls by the force the force table names at each robot's step: its
target (centroid, hands, feet) and the range its magnitudes are drawn from (a continuous 0-100 N apart from
150-200 N impulses). ``study.scripts.force_exposure`` is the command line.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace
from typing import Any

import numpy as np

from zerith_gym.core.disturbances import FORCE_TARGET_NAMES, ForceCycle
from zerith_gym.core.scenarios import SCENARIOS, Scenario, scaled_scenario


def training_scenario(name: str, scale: float, start_phases: Sequence[int] | None = None) -> Scenario:
    """The scenario `name` scaled like a curriculum stage, its force cycle's start phases replaced when
    `start_phases` is given (a ValueError if the scenario has no force cycle)."""
    scenario = scaled_scenario(SCENARIOS[name], scale)
    if start_phases is None:
        return scenario
    if not isinstance(scenario.force, ForceCycle):
        raise ValueError(f"{name!r} has no force cycle whose start phases could be replaced")
    return replace(scenario, force=replace(scenario.force, start_phases=tuple(start_phases)))


def exposure(model: Any, normalizer: Any | None, env: Any, num_steps: int) -> tuple[np.ndarray, ...]:
    """Run `model`'s stochastic policy on the batched `env` for `num_steps` steps. Returns the kinds of force
    its scenario's table names, (k, 3) rows of target index and magnitude range, and the robot-steps and
    falls under each (a fall counts under the force of its last step)."""
    task = env.robots.task
    forces = np.stack([task.arrays.force_target, *task.arrays.force_magnitude.T], axis=1)
    kinds, kind_of_step = np.unique(forces, axis=0, return_inverse=True)
    kind_of_step = kind_of_step.ravel()
    steps, falls = np.zeros(len(kinds), dtype=int), np.zeros(len(kinds), dtype=int)
    obs = env.reset()
    for _ in range(num_steps):
        state = task.state
        kind = kind_of_step[state.step_count + state.force_offset]
        np.add.at(steps, kind, 1)
        actions, _ = model.predict(normalizer.normalize_obs(obs) if normalizer else obs, deterministic=False)
        obs, _, dones, infos = env.step(actions)
        for i in np.flatnonzero(dones):
            falls[kind[i]] += bool(infos[i]["fall"])
    return kinds, steps, falls


def exposure_table(kinds: np.ndarray, steps: np.ndarray, falls: np.ndarray) -> str:
    """`exposure`'s counts as a markdown table: each force's share of the robot-steps and its fall rate."""
    lines = [
        "| target | force (N) | share of robot-steps | falls | falls per 1,000 robot-steps |",
        "|---|---|---|---|---|",
    ]
    targets = list(FORCE_TARGET_NAMES)
    for (target, low, high), kind_steps, kind_falls in zip(kinds, steps, falls, strict=True):
        rate = 1000 * kind_falls / kind_steps if kind_steps else float("nan")
        share = f"{kind_steps / steps.sum():.3f}"
        lines.append(
            f"| {targets[int(target)]} | {low:.0f}-{high:.0f} | {share} | {kind_falls:.0f} | {rate:.2f} |"
        )
    return "\n".join(lines)
