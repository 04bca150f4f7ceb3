"""MJX side of the GPU backend: the model on the device, per-robot model fields, reset and control step.

The same MJCF and terrain as the CPU backend (`zerith_gym.physics.build_model`), with two differences
that MJX imposes, both invisible to the task:

- MJX has no contact sensors with body or subtree matching. The model is put on the device without the
  three contact sensors (feet forces, leg collision), and `MjxPhysics.sensordata` computes them from
  MJX's contacts, appended where the CPU model has them, so the task reads one sensor layout.
- MJX raises no bad-state warnings. A simulation counts as unstable when a sub-step leaves non-finite
  or huge (beyond MuJoCo's 1e10 bound) positions, velocities or accelerations; the task then truncates
  the episode, as on the CPU.

Every function works on one robot and is `jax.vmap`ped over the batch; the randomized model fields
(`zerith_gym.physics.RANDOMIZED_FIELDS`) are batched, the rest of the model is shared.
"""

from __future__ import annotations

from dataclasses import dataclass

import jax
import jax.numpy as jnp
import mujoco
import numpy as np
from mujoco import mjx
from mujoco.mjx._src.support import contact_force_dim

from zerith_gym import robot
from zerith_gym.disturbances import FORCE_TARGETS
from zerith_gym.physics import GROUND_CLEARANCE, NominalModel, build_model, lowest_sole_clearance
from zerith_gym.terrain import Terrain

CONTACT_SENSORS = ("left_foot_force", "right_foot_force", "leg_collision")
"""The MJCF's contact sensors, which MJX cannot evaluate: computed from MJX's contacts instead."""
UNSTABLE_BOUND = 1e10
"""MuJoCo's bad-state bound (mjMAXVAL) on positions, velocities and accelerations."""


@dataclass(frozen=True)
class SolverSettings:
    """Constraint solver iterations of the MJX model (the MJCF's, 100 / 50, unless given)."""

    iterations: int | None = None
    ls_iterations: int | None = None


class MjxPhysics:
    """The Zerith-1 model on the device, for one terrain.

    `model` (CPU, with the contact sensors) gives the sensor layout and the nominal values; `device_model`
    is the MJX model without the contact sensors.
    """

    def __init__(self, terrain: Terrain, solver: SolverSettings = SolverSettings()) -> None:
        self.terrain = terrain
        self.model = build_model(terrain)
        self.nominal = NominalModel.capture(self.model, terrain)
        stripped = _without_contact_sensors(terrain)
        for name, value in (("iterations", solver.iterations), ("ls_iterations", solver.ls_iterations)):
            if value is not None:
                if not isinstance(value, int) or value < 1:
                    raise ValueError(f"solver {name} must be a positive integer, got {value!r}")
                setattr(stripped.opt, name, value)
        self.solver = SolverSettings(stripped.opt.iterations, stripped.opt.ls_iterations)
        self.device_model = mjx.put_model(stripped)
        self._template = mjx.make_data(self.device_model)
        self._check_sensor_layout(stripped)
        # Which bodies each force target pushes: (targets, nbody) of 0 / 1.
        self._force_mask = np.zeros((len(FORCE_TARGETS), self.model.nbody))
        for index, names in enumerate(FORCE_TARGETS.values()):
            self._force_mask[index, [self.model.body(name).id for name in names]] = 1.0
        self._soles = self.nominal.sole_geoms
        self._sole_radius = jnp.asarray(self.nominal.sole_radius)
        self._contacts = _ContactMap.of(self.model, self._template, terrain.ground_geoms)

    def _check_sensor_layout(self, stripped: mujoco.MjModel) -> None:
        layout = robot.Sensors.layout(self.model)
        contact = [layout.foot_force, layout.leg_collision]
        if [block.start for block in contact] != [stripped.nsensordata, stripped.nsensordata + 6]:
            raise RuntimeError("the contact sensors must be the last sensors of the MJCF, feet then legs")
        self.nsensordata = self.model.nsensordata

    # --------------------------------------------------------------------------- one robot each
    def with_fields(self, fields: dict[str, jax.Array]) -> mjx.Model:
        """The device model with one robot's randomized fields."""
        return self.device_model.replace(**fields)

    def reset(self, fields: dict[str, jax.Array], qpos: jax.Array) -> mjx.Data:
        """One robot at rest at `qpos` (base height 0), lowered so its soles just clear the ground."""
        model = self.with_fields(fields)
        data = self._template.replace(qpos=qpos, ctrl=jnp.asarray(robot.DEFAULT_JOINT_POS, qpos.dtype))
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

        `force` (3,) acts on each body of force target `force_target` (an index of `FORCE_TARGETS`),
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
        return jnp.concatenate([data.sensordata, self._contacts.readings(self.device_model, data)])


@dataclass(frozen=True)
class _ContactMap:
    """Look-up tables from geom id to its role in the contact readings (index -1, an empty slot, is last)."""

    is_ground: np.ndarray  # (ngeom + 1,) bool
    foot: np.ndarray  # (ngeom + 1,) 0 left foot, 1 right foot, 2 neither
    leg: np.ndarray  # (ngeom + 1,) 0 left leg, 1 right leg, 2 neither

    @staticmethod
    def of(model: mujoco.MjModel, template: mjx.Data, ground_geoms: tuple[str, ...]) -> _ContactMap:
        if not (np.asarray(template._impl.contact.dim) == 3).all():
            raise RuntimeError("the MJX contact readings expect condim 3 on every contact")
        is_ground = np.zeros(model.ngeom + 1, dtype=bool)
        is_ground[[model.geom(name).id for name in ground_geoms]] = True
        foot = np.full(model.ngeom + 1, 2)
        for index, geoms in enumerate(robot.SOLE_GEOMS):
            foot[[model.geom(name).id for name in geoms]] = index
        leg = np.full(model.ngeom + 1, 2)
        leg[_subtree_geoms(model, "left_hip_yaw_link")] = 0
        leg[_subtree_geoms(model, "right_hip_yaw_link")] = 1
        return _ContactMap(is_ground, foot, leg)

    def readings(self, device_model: mjx.Model, data: mjx.Data) -> jax.Array:
        """Ground force on each foot in the world frame (6,) and the legs' contact count (1,)."""
        contact = data._impl.contact
        is_ground, foot, leg = jnp.asarray(self.is_ground), jnp.asarray(self.foot), jnp.asarray(self.leg)
        force, index = contact_force_dim(device_model, data, 3)  # every contact has condim 3
        world = jnp.einsum("ci,cij->cj", force[:, :3], contact.frame[index])  # on geom 2, world frame
        first, second = contact.geom[index, 0], contact.geom[index, 1]
        feet = jnp.arange(2)[:, None]
        sign = (is_ground[first] & (foot[second] == feet)).astype(world.dtype) - (
            is_ground[second] & (foot[first] == feet)
        ).astype(world.dtype)  # (2, contacts): the ground's force on each foot
        foot_force = (sign @ world).reshape(6)
        legs = leg[contact.geom[:, 0]] + leg[contact.geom[:, 1]] == 1  # a left and a right leg geom
        touching = (contact.dist < 0) & legs & (contact.geom[:, 0] >= 0)
        return jnp.concatenate([foot_force, touching.sum(keepdims=True).astype(world.dtype)])


def _without_contact_sensors(terrain: Terrain) -> mujoco.MjModel:
    spec = mujoco.MjSpec.from_file(str(robot.ASSET_PATH))
    terrain.add_to(spec)
    for name in CONTACT_SENSORS:
        spec.delete(spec.sensor(name))
    model = spec.compile()
    model.opt.timestep = robot.PHYSICS_DT
    return model


def _subtree_geoms(model: mujoco.MjModel, root: str) -> np.ndarray:
    """Geoms of the bodies in the subtree of body `root`."""
    root_id = model.body(root).id
    bodies = [b for b in range(model.nbody) if _is_in_subtree(model, b, root_id)]
    return np.flatnonzero(np.isin(model.geom_bodyid, bodies))


def _is_in_subtree(model: mujoco.MjModel, body: int, root: int) -> bool:
    while body != root and body != 0:
        body = model.body_parentid[body]
    return body == root
