"""MJX side of the GPU backend: the model on the device, per-robot model fields, reset and control step.

The same MJCF and terrain as the CPU backend (`zerith_gym.core.physics.build_model`), with two differences
that MJX imposes, both invisible to the task:

- MJX has no contact sensors with body or subtree matching. The model is put on the device without its
  contact sensors (Zerith-1's feet forces and leg collision, the quadruped's feet forces and base and leg
  contacts), and `MjxPhysics.sensordata` computes them from MJX's contacts, read from the MJCF's own
  declarations (`_ContactSensor`) and appended where the CPU model has them, so the task reads one layout.
- MJX raises no bad-state warnings. A simulation counts as unstable when a sub-step leaves non-finite
  or huge (beyond MuJoCo's 1e10 bound) positions, velocities or accelerations; the task then truncates
  the episode, as on the CPU.

Every function works on one robot and is `jax.vmap`ped over the batch; the randomized model fields
(`zerith_gym.core.physics.RANDOMIZED_FIELDS`) are batched, the rest of the model is shared.
"""

from __future__ import annotations

from dataclasses import dataclass

import jax
import jax.numpy as jnp
import mujoco
import numpy as np
from mujoco import mjx
from mujoco.mjx._src.support import contact_force_dim

from zerith_gym.core.disturbances import FORCE_TARGET_NAMES
from zerith_gym.core.physics import GROUND_CLEARANCE, NominalModel, build_model, lowest_sole_clearance
from zerith_gym.core.spec import RobotSpec
from zerith_gym.terrain.ground import Terrain

UNSTABLE_BOUND = 1e10
"""MuJoCo's bad-state bound (mjMAXVAL) on positions, velocities and accelerations."""


@dataclass(frozen=True)
class SolverSettings:
    """Constraint solver iterations of the MJX model (the MJCF's, 100 / 50, unless given)."""

    iterations: int | None = None
    ls_iterations: int | None = None


class MjxPhysics:
    """A robot's model (Zerith-1's unless given) on the device, for one terrain.

    `model` (CPU, with the contact sensors) gives the sensor layout and the nominal values; `device_model`
    is the MJX model without the contact sensors.
    """

    def __init__(self, terrain: Terrain, solver: SolverSettings, robot: RobotSpec) -> None:
        self.terrain = terrain
        self.model = build_model(terrain, robot)
        self.nominal = NominalModel.capture(self.model, terrain, robot)
        stripped = _without_contact_sensors(terrain, robot)
        for name, value in (("iterations", solver.iterations), ("ls_iterations", solver.ls_iterations)):
            if value is not None:
                if not isinstance(value, int) or value < 1:
                    raise ValueError(f"solver {name} must be a positive integer, got {value!r}")
                setattr(stripped.opt, name, value)
        self.solver = SolverSettings(stripped.opt.iterations, stripped.opt.ls_iterations)
        self.device_model = mjx.put_model(stripped)
        self._template = mjx.make_data(self.device_model)
        # Which bodies each force target pushes: (targets, nbody) of 0 / 1.
        self._force_mask = np.zeros((len(FORCE_TARGET_NAMES), self.model.nbody))
        for index, target in enumerate(FORCE_TARGET_NAMES):
            bodies = [self.model.body(name).id for name in robot.force_bodies.get(target, ())]
            self._force_mask[index, bodies] = 1.0
        self._soles = self.nominal.sole_geoms
        self._sole_radius = jnp.asarray(self.nominal.sole_radius)
        self._ctrl = jnp.asarray(self.nominal.default_ctrl)
        if not (np.asarray(self._template._impl.contact.dim) == 3).all():
            raise RuntimeError("the MJX contact readings expect condim 3 on every contact")
        self._contacts = _contact_sensors(self.model, stripped)
        self.nsensordata = self.model.nsensordata

    # --------------------------------------------------------------------------- one robot each
    def with_fields(self, fields: dict[str, jax.Array]) -> mjx.Model:
        """The device model with one robot's randomized fields."""
        return self.device_model.replace(**fields)

    def reset(self, fields: dict[str, jax.Array], qpos: jax.Array) -> mjx.Data:
        """One robot at rest at `qpos` (base height 0), lowered so its soles just clear the ground."""
        model = self.with_fields(fields)
        data = self._template.replace(qpos=qpos, ctrl=self._ctrl.astype(qpos.dtype))
        data = mjx.kinematics(model, data)
        lowest = lowest_sole_clearance(data.geom_xpos[self._soles][None], self._sole_radius, self.terrain)[0]
        data = data.replace(qpos=qpos.at[2].set(qpos[2] - lowest + GROUND_CLEARANCE))
        return mjx.forward(model, data)

    def control_step(
        self,
        fields: dict[str, jax.Array],
        data: mjx.Data,
        targets: jax.Array,
        lags: jax.Array,
        force: jax.Array,
        force_target: jax.Array,
        kicks: jax.Array,
    ) -> tuple[mjx.Data, jax.Array]:
        """One control step of one robot: sub-step j applies `targets[lags[j]]` (targets (3, 12) by lag).

        `force` (3,) acts on each body of force target `force_target` (an index of `FORCE_TARGET_NAMES`),
        `kicks` (2,) is added to the base's horizontal velocity. Returns the data and whether the
        simulation became unstable.
        """
        model = self.with_fields(fields)
        on_body = jnp.asarray(self._force_mask)[force_target]  # (nbody,)
        xfrc = data.xfrc_applied.at[:, :3].set(on_body[:, None] * force)
        data = data.replace(xfrc_applied=xfrc, qvel=data.qvel.at[:2].add(kicks))

        def substep(data: mjx.Data, lag: jax.Array) -> tuple[mjx.Data, jax.Array]:
            data = mjx.step(model, data.replace(ctrl=targets[lag]))
            state = jnp.concatenate([data.qpos, data.qvel, data.qacc])
            return data, ~jnp.all(jnp.isfinite(state) & (jnp.abs(state) < UNSTABLE_BOUND))

        data, unstable = jax.lax.scan(substep, data, lags)
        return data, unstable.any()

    def sensordata(self, data: mjx.Data) -> jax.Array:
        """One robot's sensor readings in the CPU model's layout: MJX's sensors, then the contact ones."""
        force, index = contact_force_dim(self.device_model, data, 3)  # every contact has condim 3
        contact = data._impl.contact
        world = jnp.einsum("ci,cij->cj", force[:, :3], contact.frame[index])  # on geom 2, world frame
        first, second = contact.geom[index, 0], contact.geom[index, 1]
        touching = (contact.dist < 0) & (contact.geom[:, 0] >= 0)
        readings = [sensor.reading(first, second, world, contact.geom, touching) for sensor in self._contacts]
        return jnp.concatenate([data.sensordata, *readings])


@dataclass(frozen=True)
class _ContactSensor:
    """One contact sensor of the MJCF, as MJX's contacts give it: which geoms are on each side (look-up
    tables over geom ids, index -1, an empty slot, last) and what it reports."""

    side1: np.ndarray  # (ngeom + 1,) bool
    side2: np.ndarray  # (ngeom + 1,) bool
    force: bool
    """True: the net force of side 1 on side 2 in the world frame (3); False: the contacts found (1)."""

    def reading(
        self, first: jax.Array, second: jax.Array, world: jax.Array, geoms: jax.Array, touching: jax.Array
    ) -> jax.Array:
        side1, side2 = jnp.asarray(self.side1), jnp.asarray(self.side2)
        if self.force:
            sign = (side1[first] & side2[second]).astype(world.dtype) - (side2[first] & side1[second]).astype(
                world.dtype
            )
            return sign @ world
        a, b = geoms[:, 0], geoms[:, 1]
        found = touching & ((side1[a] & side2[b]) | (side2[a] & side1[b]))
        return found.sum(keepdims=True).astype(world.dtype)


def _contact_sensors(model: mujoco.MjModel, stripped: mujoco.MjModel) -> list[_ContactSensor]:
    """The model's contact sensors, in order; RuntimeError unless they are its last sensors, each a body or
    subtree on each side reporting the net force or the contacts found."""
    sensors, start = [], stripped.nsensordata
    for i in np.flatnonzero(model.sensor_type == mujoco.mjtSensor.mjSENS_CONTACT):
        if model.sensor_adr[i] != start:
            raise RuntimeError("the contact sensors must be the last sensors of the MJCF")
        sides = [
            _side_geoms(model, int(kind), int(index))
            for kind, index in ((model.sensor_objtype[i], model.sensor_objid[i]),
                                (model.sensor_reftype[i], model.sensor_refid[i]))
        ]  # fmt: skip
        sensors.append(_ContactSensor(*sides, force=bool(model.sensor_dim[i] == 3)))
        start += int(model.sensor_dim[i])
    if start != model.nsensordata:
        raise RuntimeError("the contact sensors must be the last sensors of the MJCF")
    return sensors


def _side_geoms(model: mujoco.MjModel, kind: int, index: int) -> np.ndarray:
    """A look-up table (ngeom + 1,) of the geoms of a body or of a body's subtree."""
    if kind == mujoco.mjtObj.mjOBJ_BODY:
        bodies = [index]
    elif kind == mujoco.mjtObj.mjOBJ_XBODY:  # a subtree
        bodies = [b for b in range(model.nbody) if _is_in_subtree(model, b, index)]
    else:
        raise RuntimeError(f"contact sensors of object type {kind} are not read on MJX")
    table = np.zeros(model.ngeom + 1, dtype=bool)
    table[np.flatnonzero(np.isin(model.geom_bodyid, bodies))] = True
    return table


def _without_contact_sensors(terrain: Terrain, robot: RobotSpec) -> mujoco.MjModel:
    spec = mujoco.MjSpec.from_file(str(robot.asset_path))
    terrain.add_to(spec)
    for sensor in [s for s in spec.sensors if s.type == mujoco.mjtSensor.mjSENS_CONTACT]:
        spec.delete(sensor)
    model = spec.compile()
    model.opt.timestep = robot.physics_dt
    return model


def _is_in_subtree(model: mujoco.MjModel, body: int, root: int) -> bool:
    while body != root and body != 0:
        body = model.body_parentid[body]
    return body == root
