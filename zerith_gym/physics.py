"""MuJoCo side of the env: building the model, applying domain parameters, resetting and stepping.

Kept apart from the task logic (`task.py`, pure numpy) so that a batched simulator can reuse both.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

from zerith_gym import robot
from zerith_gym.randomization import NUM_LINKS, DomainParams
from zerith_gym.terrain import Terrain

BAD_STATE_WARNINGS = slice(int(mujoco.mjtWarning.mjWARN_BADQPOS), int(mujoco.mjtWarning.mjWARN_BADQACC) + 1)
if BAD_STATE_WARNINGS.stop - BAD_STATE_WARNINGS.start != 3:
    raise RuntimeError("MuJoCo's bad qpos, qvel and qacc warnings are expected to be contiguous")
GROUND_CLEARANCE = 0.002
"""Gap (m) left between the lowest foot corner and the ground when the robot is placed at reset."""


def build_model(terrain: Terrain) -> mujoco.MjModel:
    """Compile the robot MJCF with the terrain's ground, at the package's physics time step."""
    spec = mujoco.MjSpec.from_file(str(robot.ASSET_PATH))
    terrain.add_to(spec)
    model = spec.compile()
    model.opt.timestep = robot.PHYSICS_DT
    return model


@dataclass(frozen=True)
class NominalModel:
    """The unrandomized values of every model field that domain randomization edits, and their indices."""

    body_mass: np.ndarray
    body_inertia: np.ndarray
    body_ipos: np.ndarray
    geom_friction: np.ndarray
    gain: np.ndarray  # kp per actuator
    damping: np.ndarray  # kv per actuator
    forcerange: np.ndarray
    root: int
    links: np.ndarray
    friction_geoms: np.ndarray
    foot_geoms: np.ndarray

    @staticmethod
    def capture(model: mujoco.MjModel, terrain: Terrain) -> NominalModel:
        root = model.body(robot.ROOT_BODY).id
        links = np.array([b for b in range(1, model.nbody) if b != root])
        if len(links) != NUM_LINKS:
            raise RuntimeError(f"expected {NUM_LINKS} non-root robot bodies, found {len(links)}")
        feet = np.array([model.geom(name).id for name in robot.FOOT_GEOMS])
        ground = np.array([model.geom(name).id for name in terrain.ground_geoms])
        return NominalModel(
            body_mass=model.body_mass.copy(),
            body_inertia=model.body_inertia.copy(),
            body_ipos=model.body_ipos.copy(),
            geom_friction=model.geom_friction.copy(),
            gain=model.actuator_gainprm[:, 0].copy(),
            damping=-model.actuator_biasprm[:, 2].copy(),
            forcerange=model.actuator_forcerange.copy(),
            root=root,
            links=links,
            friction_geoms=np.concatenate([feet, ground]),
            foot_geoms=feet,
        )


def apply_domain(model: mujoco.MjModel, nominal: NominalModel, params: DomainParams) -> None:
    """Write one robot's domain parameters (a batch of one) into its model, starting from nominal values."""
    root, links = nominal.root, nominal.links
    model.body_mass[:] = nominal.body_mass
    model.body_inertia[:] = nominal.body_inertia
    model.body_ipos[:] = nominal.body_ipos
    root_scale = 1.0 + params.added_mass[0, 0] / nominal.body_mass[root]
    model.body_mass[root] *= root_scale
    model.body_inertia[root] *= root_scale
    model.body_ipos[root] += params.com_offset[0]
    model.body_mass[links] *= params.link_mass_scale[0]
    model.body_inertia[links] *= params.link_mass_scale[0][:, None]
    model.geom_friction[:] = nominal.geom_friction
    model.geom_friction[nominal.friction_geoms, 0] = params.friction[0, 0]
    strength = params.motor_strength[0]
    kp = nominal.gain * strength * params.kp_scale[0]
    model.actuator_gainprm[:, 0] = kp
    model.actuator_biasprm[:, 1] = -kp
    model.actuator_biasprm[:, 2] = -nominal.damping * strength * params.kd_scale[0]
    model.actuator_forcerange[:] = nominal.forcerange * strength[:, None]


def reset_state(
    model: mujoco.MjModel, data: mujoco.MjData, qpos: np.ndarray, terrain: Terrain, foot_geoms: np.ndarray
) -> None:
    """Set the robot at rest at `qpos`, lowered so its lowest foot corner just clears the ground."""
    mujoco.mj_resetData(model, data)
    data.qpos[:] = qpos
    data.ctrl[:] = robot.DEFAULT_JOINT_POS
    mujoco.mj_kinematics(model, data)
    corners = np.array([[sx, sy, -1.0] for sx in (-1.0, 1.0) for sy in (-1.0, 1.0)])
    lowest = np.inf
    for g in foot_geoms:
        points = data.geom_xpos[g] + (corners * model.geom_size[g]) @ data.geom_xmat[g].reshape(3, 3).T
        lowest = min(lowest, float(np.min(points[:, 2] - terrain.height_at(points[:, :2]))))
    data.qpos[2] = qpos[2] - lowest + GROUND_CLEARANCE
    mujoco.mj_forward(model, data)
