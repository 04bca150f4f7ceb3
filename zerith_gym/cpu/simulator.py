"""MuJoCo simulation of n robots of one kind (Zerith-1, the Go2-like quadruped): one model and data per robot.

Each robot has its own `MjModel` copy because domain randomization edits model fields (masses, friction,
gains) per robot. A control step of robot i is a few `mj_step(model, data, nstep)` calls in C, one per
run of sub-steps that share a delayed action (usually one call): no Python per physics sub-step.
The single env is this with n = 1, so single and batched envs share every line of physics code.

With `threads > 1` the robots are split into that many contiguous groups stepped by a thread pool. MuJoCo's
Python bindings release the GIL inside `mj_step`, so the groups' physics runs in parallel; each robot still
gets exactly the same calls on its own model and data, so the results do not depend on the thread count.

(MuJoCo's threaded `mujoco.rollout` was measured against this loop: see docs/performance.md for why the
loop is used: rollouts restart from a state vector without the solver's warm start, and MuJoCo's
per-robot bad-state warnings are not visible through them.)
"""

from __future__ import annotations

import copy
from concurrent.futures import ThreadPoolExecutor
from typing import NamedTuple

import mujoco
import numpy as np

from zerith_gym.core.disturbances import FORCE_TARGET_NAMES
from zerith_gym.core.physics import BAD_STATE_WARNINGS, NominalModel, apply_domain, build_model, reset_states
from zerith_gym.core.randomization import DomainParams
from zerith_gym.core.spec import RobotSpec
from zerith_gym.terrain.ground import Terrain

Segments = list[tuple[int, int]]
"""Runs of physics sub-steps applying the same action: (lag in control steps, number of sub-steps)."""


def lag_segments(lags: np.ndarray) -> Segments:
    """Group one robot's per-sub-step lags (decimation,) into runs, oldest action first.

    Lags never increase within a control step (a later sub-step never applies an older action), so
    each lag forms one contiguous run.
    """
    values = lags.tolist()
    return [(lag, values.count(lag)) for lag in sorted(set(values), reverse=True)]


class _Robot(NamedTuple):
    """One robot's model and data, and persistent views of the data fields touched every step."""

    model: mujoco.MjModel
    data: mujoco.MjData
    ctrl: np.ndarray
    qvel: np.ndarray
    sensordata: np.ndarray
    bad_state_warnings: np.ndarray
    force_rows: list[list[np.ndarray]]  # per force target, xfrc_applied[body, :3] of each of its bodies

    @staticmethod
    def of(model: mujoco.MjModel, force_bodies: list[list[int]]) -> _Robot:
        data = mujoco.MjData(model)
        return _Robot(
            model,
            data,
            data.ctrl,
            data.qvel,
            data.sensordata,
            data.warning.number[BAD_STATE_WARNINGS],
            [[data.xfrc_applied[body, :3] for body in bodies] for bodies in force_bodies],
        )


class Simulator:
    """The physics of `num_robots` robots on one terrain, with external forces on the bodies of a target.

    `threads`: how many threads step the robots' physics (at most one per robot); `robot`: which robot.
    """

    def __init__(self, num_robots: int, terrain: Terrain, robot: RobotSpec, threads: int = 1) -> None:
        if not isinstance(threads, int | np.integer) or threads < 1:
            raise ValueError(f"the number of physics threads must be a positive integer, got {threads!r}")
        model = build_model(terrain, robot)
        self.terrain = terrain
        self.models = [model] + [copy.copy(model) for _ in range(num_robots - 1)]
        bodies = [[model.body(name).id for name in robot.force_bodies.get(t, ())] for t in FORCE_TARGET_NAMES]
        self._robots = [_Robot.of(m, bodies) for m in self.models]
        self.datas = [robot_.data for robot_ in self._robots]
        self.nominal = NominalModel.capture(model, terrain, robot)
        self.sensordata = np.zeros((num_robots, model.nsensordata))
        """Every robot's sensor readings after the last reset or step, (num_robots, nsensordata)."""
        self._qvel = np.zeros((num_robots, model.nv))
        self._segments: list[Segments] = [[(0, robot.decimation)]] * num_robots
        self._warned = np.zeros(num_robots, dtype=bool)
        self._force_target = [0] * num_robots  # the target whose bodies each robot's force was last set on
        groups = min(int(threads), num_robots)
        self._groups = [group.tolist() for group in np.array_split(np.arange(num_robots), groups)]
        self._pool = ThreadPoolExecutor(groups - 1, "zerith-physics") if groups > 1 else None

    def reset(self, ids: np.ndarray, domain: DomainParams, qpos: np.ndarray, lags: np.ndarray) -> None:
        """Restart robots `ids` with their domain parameters, initial positions and lags (row k: ids[k])."""
        ids = ids.tolist()
        models, datas = [self.models[i] for i in ids], [self.datas[i] for i in ids]
        apply_domain(models, self.nominal, domain)
        reset_states(models, datas, qpos, self.terrain, self.nominal)
        for k, i in enumerate(ids):
            self._segments[i] = lag_segments(lags[k])
            self.sensordata[i] = datas[k].sensordata

    def step(
        self,
        targets: np.ndarray,
        force: np.ndarray,
        force_target: np.ndarray,
        kicks: np.ndarray | None,
        other_forces: np.ndarray | None = None,
    ) -> np.ndarray:
        """One control step of every robot; returns which simulations became unstable, (num_robots,) bool.

        `targets` (n, lags, 12): joint targets by lag; `force` (n, 3): the force on each body of the
        robot's `force_target` (n,) (an index of `FORCE_TARGET_NAMES`), none on the other targets' bodies;
        `kicks` (n, 2): horizontal velocity added to the base, or None; `other_forces` (n, k, 3): the
        forces on the target's second, third, ... bodies where they differ from the first's (per-body
        draws), or None. A simulation is unstable if MuJoCo raised a bad-state warning during the step (it
        then resets the state) or if it ends with non-finite velocities.
        """
        inputs = (targets, force, force_target.tolist(), kicks, other_forces)
        if self._pool is None:
            self._step_robots(self._groups[0], *inputs)
        else:  # the calling thread steps the first group while the pool steps the others
            others = [self._pool.submit(self._step_robots, group, *inputs) for group in self._groups[1:]]
            self._step_robots(self._groups[0], *inputs)
            for future in others:
                future.result()
        return self._warned | ~np.isfinite(self._qvel).all(axis=1)

    def close(self) -> None:
        """Stop the physics threads, if any."""
        if self._pool is not None:
            self._pool.shutdown()
            self._pool = None
            self._groups = [list(range(len(self._robots)))]

    def _step_robots(
        self,
        ids: list[int],
        targets: np.ndarray,
        force: np.ndarray,
        force_target: list[int],
        kicks: np.ndarray | None,
        other_forces: np.ndarray | None,
    ) -> None:
        """Step robots `ids`, writing their velocities, sensors and warning flags into the batch arrays."""
        for i in ids:
            sim = self._robots[i]
            target = force_target[i]
            if target != self._force_target[i]:  # the previous target's bodies are free again
                for row in sim.force_rows[self._force_target[i]]:
                    row[:] = 0.0
                self._force_target[i] = target
            for row in sim.force_rows[target]:
                row[:] = force[i]
            if other_forces is not None:  # per-body draws: the second body on gets its own
                for row, own in zip(sim.force_rows[target][1:], other_forces[i], strict=False):
                    row[:] = own
            if kicks is not None:
                sim.qvel[:2] += kicks[i]
            warnings = sim.bad_state_warnings.tolist()
            robot_targets = targets[i]
            for lag, count in self._segments[i]:
                sim.ctrl[:] = robot_targets[lag]
                mujoco.mj_step(sim.model, sim.data, nstep=count)
            self._warned[i] = sim.bad_state_warnings.tolist() != warnings
            self._qvel[i] = sim.qvel
            self.sensordata[i] = sim.sensordata
