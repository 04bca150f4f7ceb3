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
    gainprm: np.ndarray
    biasprm: np.ndarray
    root: int
    links: np.ndarray
    friction_geoms: np.ndarray
    foot_geoms: np.ndarray
    foot_size: np.ndarray  # half sizes of the foot boxes (feet, 3)

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
            gainprm=model.actuator_gainprm.copy(),
            biasprm=model.actuator_biasprm.copy(),
            root=root,
            links=links,
            friction_geoms=np.concatenate([feet, ground]),
            foot_geoms=feet,
            foot_size=model.geom_size[feet].copy(),
        )


def apply_domain(models: list[mujoco.MjModel], nominal: NominalModel, params: DomainParams) -> None:
    """Write robot k's domain parameters (row k of `params`) into `models[k]`, from the nominal values.

    The randomized fields of all robots are computed together, then copied into each model.
    """
    n, root, links = len(models), nominal.root, nominal.links
    mass = np.repeat(nominal.body_mass[None], n, axis=0)
    inertia = np.repeat(nominal.body_inertia[None], n, axis=0)
    ipos = np.repeat(nominal.body_ipos[None], n, axis=0)
    root_scale = 1.0 + params.added_mass[:, 0] / nominal.body_mass[root]
    mass[:, root] *= root_scale
    inertia[:, root] *= root_scale[:, None]
    ipos[:, root] += params.com_offset
    mass[:, links] *= params.link_mass_scale
    inertia[:, links] *= params.link_mass_scale[:, :, None]
    friction = np.repeat(nominal.geom_friction[None], n, axis=0)
    friction[:, nominal.friction_geoms, 0] = params.friction
    strength = params.motor_strength
    kp = nominal.gain * strength * params.kp_scale
    gainprm = np.repeat(nominal.gainprm[None], n, axis=0)
    gainprm[:, :, 0] = kp
    biasprm = np.repeat(nominal.biasprm[None], n, axis=0)
    biasprm[:, :, 1] = -kp
    biasprm[:, :, 2] = -nominal.damping * strength * params.kd_scale
    fields = {
        "body_mass": mass,
        "body_inertia": inertia,
        "body_ipos": ipos,
        "geom_friction": friction,
        "actuator_gainprm": gainprm,
        "actuator_biasprm": biasprm,
        "actuator_forcerange": nominal.forcerange * strength[:, :, None],
    }
    for k, model in enumerate(models):
        for name, values in fields.items():
            getattr(model, name)[:] = values[k]


_SOLE_CORNERS = np.array([[sx, sy, -1.0] for sx in (-1.0, 1.0) for sy in (-1.0, 1.0)])
"""Bottom corners of a box geom, in units of its half sizes."""


def reset_states(
    models: list[mujoco.MjModel],
    datas: list[mujoco.MjData],
    qpos: np.ndarray,
    terrain: Terrain,
    nominal: NominalModel,
) -> None:
    """Set robot k at rest at `qpos[k]`, lowered so its lowest foot corner just clears the ground."""
    feet = nominal.foot_geoms
    for model, data, q in zip(models, datas, qpos, strict=True):
        mujoco.mj_resetData(model, data)
        data.qpos[:] = q
        data.ctrl[:] = robot.DEFAULT_JOINT_POS
        mujoco.mj_kinematics(model, data)
    centre = np.array([data.geom_xpos[feet] for data in datas])  # (n, feet, 3)
    rotation = np.array([data.geom_xmat[feet] for data in datas]).reshape(len(datas), len(feet), 3, 3)
    corners = centre[:, :, None] + (_SOLE_CORNERS * nominal.foot_size[:, None]) @ rotation.swapaxes(-1, -2)
    clearance = corners[..., 2] - terrain.height_at(corners[..., :2])  # (n, feet, corners)
    lowest = np.minimum.reduce(clearance.reshape(len(datas), -1), axis=1)
    for model, data, q, low in zip(models, datas, qpos, lowest.tolist(), strict=True):
        data.qpos[2] = q[2] - low + GROUND_CLEARANCE
        mujoco.mj_forward(model, data)
