"""n robots on MJX (Zerith-1 or the quadruped): the task state as a JAX pytree, jitted reset and step.

The task is the CPU backend's: `reset_values`, `begin_step`, `end_step` from `zerith_gym.core.task` and the
robot's `LocomotionTask` (its `observe` and `judge`), on the same `TaskState` record, the domain fields from
`zerith_gym.core.physics.domain_model_fields`, all traced with jax.numpy. What differs is only what JAX
needs: the state is an immutable pytree (`MjxState`) replaced every step, randomness comes from one JAX
key split every step (not one numpy generator per robot), and robots whose episode ended are reset
inside the same jitted step (when any did, every robot's reset is computed and selected where one did).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
from mujoco import mjx

from zerith_gym.core.contract import BatchStep, check_num_robots, check_scenario_change
from zerith_gym.core.physics import domain_model_fields
from zerith_gym.core.randomization import DomainParams
from zerith_gym.core.scenarios import Scenario
from zerith_gym.core.spec import read_sensors
from zerith_gym.core.task import (
    ScenarioArrays,
    TaskConstants,
    TaskState,
    begin_step,
    end_step,
    observation_noise,
    reset_values,
    scenario_arrays,
    task_constants,
)
from zerith_gym.mjx.physics import MjxPhysics, SolverSettings
from zerith_gym.options import ZerithOptions, resolve_reward_weights
from zerith_gym.terrain.ground import Terrain
from zerith_gym.terrain.levels import LevelRule, TerrainLevels


class MjxState(NamedTuple):
    """Physics and task state of n robots (leading axis n), on the device."""

    data: mjx.Data
    fields: dict[str, jax.Array]  # the randomized model fields of each robot
    key: jax.Array
    task: TaskState  # the CPU task's record, of JAX arrays


class MjxBatch:
    """`num_robots` robots on MJX in one scenario (the robots contract, `zerith_gym.core.contract.Robots`).

    Reset and step are jitted functions of the state (one compile each, at the first call); numpy arrays
    come in and go out, so `ZerithVecEnv` drives either backend.
    """

    def __init__(self, num_robots: int, options: ZerithOptions, solver: SolverSettings | None = None) -> None:
        self.num_robots = check_num_robots(num_robots)
        self.options = options
        self.scenario = options.resolved_scenario
        self.terrain = Terrain(self.scenario.terrain, seed=options.terrain_seed)
        self.task = task = options.task
        self.physics = MjxPhysics(self.terrain, solver, task.robot)
        model = self.physics.model
        self.sensors = task.robot.sensor_layout(model)
        self.constants: TaskConstants = task_constants(
            self.terrain,
            np.array([model.joint(name).range for name in task.robot.joint_names]),
            resolve_reward_weights(options.reward_weights, task.reward_weights),
            int(options.episode_steps),
            task,
        )
        # Each robot keeps its first tile: no curriculum on MJX.
        tiles = TerrainLevels(self.terrain.spec, np.arange(num_robots), task.robot.control_dt)
        self._spawn, self._levels = tiles.spawn_points(np.arange(num_robots)), tiles.levels
        self._columns = tiles.columns
        self.set_scenario(self.scenario)
        self._reset = jax.jit(self._start)
        self._step = jax.jit(self._step_all)
        self.state: MjxState | None = None
        self._seed: int | None = None

    def set_scenario(self, scenario: Scenario) -> None:
        """Follow `scenario` from now on (the arrays change, the compiled functions stay)."""
        check_scenario_change(self.scenario, scenario)
        self.scenario = scenario
        for target in scenario.force.targets:
            self.task.robot.force_target_bodies(target)
        command, steps = self.options.fixed_command(scenario), self.constants.episode_steps
        arrays = scenario_arrays(scenario, command, steps, self.task)
        if arrays.force_per_body.any():
            raise ValueError(
                f"scenario {scenario.name!r} draws a force per body (ForceSchedule.per_body): the cpu "
                "backend draws those; the MJX backend draws one vector per target"
            )
        self.arrays = ScenarioArrays(*(jnp.asarray(value) for value in arrays))

    # ------------------------------------------------- the robots contract (zerith_gym.core.contract.Robots)
    def set_level_rule(self, rule: LevelRule | None) -> None:
        """Not on MJX: its robots keep their starting tiles (ValueError unless `rule` is None)."""
        if rule is not None:
            raise ValueError(
                "the MJX backend keeps each robot on its starting tile: a terrain curriculum needs the cpu "
                "backend"
            )

    def seed(self, seeds: Mapping[int, np.random.Generator]) -> None:
        """Seed the next reset: the JAX key is drawn from the generator of the lowest robot index given."""
        if seeds:
            self._seed = int(seeds[min(seeds)].integers(2**63))

    def reset(
        self,
        ids: np.ndarray,
        commands: Mapping[int, np.ndarray] | None = None,
        tiles: Mapping[int, tuple[int, int]] | None = None,
    ) -> tuple[np.ndarray, np.ndarray]:
        """Start new episodes of every robot (`ids` must be all of them); `commands` fixes some robots'
        commands for the episode. Returns their policy and critic observations. Each robot keeps its
        starting tile: `tiles` may only name those (ValueError otherwise)."""
        for i, tile in (tiles or {}).items():
            if tuple(tile) != (self._levels[i], self._columns[i]):
                raise ValueError(
                    f"the MJX backend keeps each robot on its starting tile (robot {i}'s is "
                    f"{(int(self._levels[i]), int(self._columns[i]))}, not {tuple(tile)}): choosing tiles "
                    "needs the cpu backend"
                )
        if sorted(np.asarray(ids).tolist()) != list(range(self.num_robots)):
            raise ValueError(
                "the MJX backend resets all robots together (ended episodes restart by themselves)"
            )
        overrides = np.full((self.num_robots, 3), np.nan)
        for i, command in (commands or {}).items():
            overrides[i] = command
        seed = self._seed if self._seed is not None else int(np.random.default_rng().integers(2**63))
        self._seed = None
        self.state = self._reset(jax.random.key(seed), self.arrays, jnp.asarray(overrides, _real()))
        return np.asarray(self.state.task.policy_obs), np.asarray(self.state.task.critic_obs)

    @property
    def commands(self) -> np.ndarray:
        """The current command of every robot, (n, 3)."""
        if self.state is None:
            raise RuntimeError("reset the robots first")
        return np.asarray(self.state.task.command, dtype=float)

    def step(self, actions: np.ndarray) -> BatchStep:
        """One control step of every robot with checked actions (n, 12), within the action space; robots
        whose episode ended restart inside the step."""
        if self.state is None:
            raise RuntimeError("reset the robots before stepping them")
        self.state, step = self._step(self.state, jnp.asarray(actions, _real()), self.arrays)
        step = jax.device_get(step)  # numpy arrays, in one transfer
        out = step.out._replace(reward=step.out.reward.astype(float), terms=step.out.terms.astype(float))
        as_float = {name: getattr(step, name).astype(float) for name in ("force", "command", "next_command")}
        return step._replace(out=out, reward_names=self.task.reward_names, **as_float)

    def close(self) -> None:
        """Nothing to stop: the device memory goes with the object."""

    # ------------------------------------------------------------------------- traced functions
    def _start(self, key: jax.Array, sc: ScenarioArrays, overrides: jax.Array) -> MjxState:
        """Fresh episodes of every robot, drawn from `key` (commands fixed where `overrides` is finite)."""
        n, task = self.num_robots, self.task
        draw, key = jax.random.split(key)
        uniforms = jax.random.uniform(draw, (n, task.draws.reset))
        spawn = jnp.asarray(self._spawn, _real())
        start = reset_values(uniforms, sc, spawn, self.terrain.spec.spawn_jitter, task.robot, task.draws)
        command = jnp.where(jnp.isfinite(overrides), overrides, start.command)
        fields = domain_model_fields(self.physics.nominal, DomainParams.from_vector(start.domain_vector))
        data = jax.vmap(self.physics.reset)(fields, start.qpos)
        readings = read_sensors(self.sensors, jax.vmap(self.physics.sensordata)(data))
        feet = len(task.robot.foot_bodies)
        state = TaskState(
            step_count=jnp.zeros(n, jnp.int32),
            force_offset=start.force_offset.astype(jnp.int32),
            gait_step=jnp.zeros(n, jnp.int32),
            command=command,
            actions=jnp.zeros((n, 3, task.robot.num_joints), _real()),
            joint_vel=readings.joint_vel,
            force=jnp.zeros_like(command),
            domain_vector=start.domain_vector,
            lags=start.lags.astype(jnp.int32),
            policy_obs=jnp.zeros((n, task.policy_size), jnp.float32),
            critic_obs=jnp.zeros((n, task.critic_size), jnp.float32),
            feet_air_time=jnp.zeros((n, feet), _real()),
            last_contact=jnp.zeros((n, feet), bool),
        )
        noise = observation_noise(start.noise_uniforms, sc, task.draws)
        policy, critic = task.observe(state, readings, noise, self.constants)
        state = state._replace(policy_obs=policy, critic_obs=critic)
        return MjxState(data=data, fields=fields, key=key, task=state)

    def _step_all(
        self, state: MjxState, actions: jax.Array, sc: ScenarioArrays
    ) -> tuple[MjxState, BatchStep]:
        n = self.num_robots
        key, draw, restart = jax.random.split(state.key, 3)
        u = jax.random.uniform(draw, (n, self.task.draws.step))
        task, drawn, targets = begin_step(state.task, actions, u, sc, self.task)
        data, unstable = jax.vmap(self.physics.control_step)(
            state.fields, state.data, targets, task.lags, drawn.force, drawn.force_target, drawn.kicks
        )
        sensordata = jnp.where(unstable[:, None], 0.0, jax.vmap(self.physics.sensordata)(data))
        readings = read_sensors(self.sensors, sensordata)
        noise = observation_noise(u, sc, self.task.draws)
        task, out = end_step(task, readings, unstable, noise, self.constants)
        stepped = state._replace(data=data, key=key, task=task)
        ended = out.terminated | out.truncated

        def restart_ended(stepped: MjxState) -> MjxState:
            fresh = self._start(restart, sc, jnp.full((n, 3), jnp.nan))
            return jax.tree.map(lambda a, b: _select_rows(ended, a, b), fresh, stepped)._replace(key=key)

        # Every robot's reset is computed and selected where an episode ended, when one did.
        new = jax.lax.cond(ended.any(), restart_ended, lambda stepped: stepped, stepped)
        level = jnp.asarray(self._levels)
        after = new.task  # the next observations and commands (a new episode's where one ended)
        step = BatchStep(
            out, drawn.force, drawn.command, after.policy_obs, after.critic_obs, after.command, level, ()
        )  # the reward names are strings, not arrays: `step` puts them back
        return new, step


def _real() -> np.dtype:
    """JAX's float type: float32, or float64 with `jax_enable_x64`."""
    return jax.dtypes.canonicalize_dtype(np.float64)


def _select_rows(rows: jax.Array, where_true: jax.Array, where_false: jax.Array) -> jax.Array:
    """Row i of `where_true` where rows[i], else of `where_false` (any trailing shape)."""
    if where_true.ndim == 0:
        return where_false
    mask = rows.reshape(rows.shape + (1,) * (where_true.ndim - 1))
    return jnp.where(mask, where_true, where_false)
