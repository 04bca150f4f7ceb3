"""MuJoCo side of the env: building the model, applying domain parameters, resetting and stepping.

Kept apart from the task logic (`task.py`, pure numpy) so that a batched simulator can reuse both.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

from zerith_gym.core.arrays import namespace
from zerith_gym.core.randomization import NUM_JOINTS, NUM_LINKS, DomainParams
from zerith_gym.core.spec import RobotSpec
from zerith_gym.terrain.ground import Terrain

BAD_STATE_WARNINGS = slice(int(mujoco.mjtWarning.mjWARN_BADQPOS), int(mujoco.mjtWarning.mjWARN_BADQACC) + 1)
if BAD_STATE_WARNINGS.stop - BAD_STATE_WARNINGS.start != 3:
    raise RuntimeError("MuJoCo's bad qpos, qvel and qacc warnings are expected to be contiguous")
GROUND_CLEARANCE = 0.002
"""Gap (m) left between the lowest sole sphere and the ground when the robot is placed at reset."""


def build_model(terrain: Terrain, robot: RobotSpec) -> mujoco.MjModel:
    """Compile the robot's MJCF with the terrain's ground, at the robot's physics time step."""
    spec = mujoco.MjSpec.from_file(str(robot.asset_path))
    terrain.add_to(spec)
    model = spec.compile()
    model.opt.timestep = robot.physics_dt
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
    sole_geoms: np.ndarray  # the spheres that touch the ground (`RobotSpec.contact_geoms`), in its order
    sole_radius: np.ndarray  # their radii
    default_ctrl: np.ndarray  # (joints,) the default pose, commanded at reset
    scale_column: np.ndarray  # per body: 0 (unscaled), 1 (root), 2 + k (link k) of the mass factors

    @staticmethod
    def capture(model: mujoco.MjModel, terrain: Terrain, robot: RobotSpec) -> NominalModel:
        root = model.body(robot.root_body).id
        links = np.array([b for b in range(1, model.nbody) if b != root])
        if len(links) != NUM_LINKS:
            raise RuntimeError(f"expected {NUM_LINKS} non-root robot bodies, found {len(links)}")
        if robot.num_joints != NUM_JOINTS:
            raise RuntimeError(f"expected {NUM_JOINTS} actuated joints, found {robot.num_joints}")
        soles = np.array([model.geom(name).id for name in robot.contact_geoms])
        ground = np.array([model.geom(name).id for name in terrain.ground_geoms])
        scale_column = np.zeros(model.nbody, dtype=int)
        scale_column[root] = 1
        scale_column[links] = 2 + np.arange(len(links))
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
            friction_geoms=np.concatenate([soles, ground]),
            sole_geoms=soles,
            sole_radius=model.geom_size[soles, 0].copy(),
            scale_column=scale_column,
            default_ctrl=robot.default_joint_pos,
        )


GROUND_FRICTION = 1.0
"""Sliding friction of the ground's material."""


def contact_friction(sole_friction: np.ndarray) -> np.ndarray:
    """Sliding friction of a sole on the ground: the mean of the two materials' frictions.

    Table 5 and Table 1 randomize the robot's own material (the paper changed the robot's insoles to test
    it on the real robot). The paper trained in Isaac Gym, whose PhysX engine gives a contact the mean of its
    two materials' frictions by default, on a ground of friction 1 (legged_gym's). MuJoCo takes the larger of
    the two geoms' frictions instead, so the env gives both the sole and the ground this mean: a drawn 0.1
    slides at 0.55, a drawn 2 at 1.5, and the nominal 1 stays 1 (docs/zerith1.md, "How friction is read").
    """
    return (sole_friction + GROUND_FRICTION) / 2


RANDOMIZED_FIELDS = (
    "body_mass",
    "body_inertia",
    "body_ipos",
    "geom_friction",
    "actuator_gainprm",
    "actuator_biasprm",
    "actuator_forcerange",
)
"""The model fields that domain randomization sets per robot."""


def domain_model_fields(nominal: NominalModel, params: DomainParams) -> dict[str, np.ndarray]:
    """Each field of `RANDOMIZED_FIELDS` for n robots (leading axis n) with domain parameters `params`.

    Numpy or JAX arrays: the CPU backend copies the rows into each robot's `MjModel`, the MJX backend
    keeps them as the batched fields of its model.
    """
    xp = namespace(params.added_mass)
    root_scale = 1.0 + params.added_mass / nominal.body_mass[nominal.root]  # (n, 1)
    # A factor per body: the load's on the root, each link's own on the links, 1 elsewhere.
    ones = xp.ones_like(root_scale)
    mass_scale = xp.concatenate([ones, root_scale, params.link_mass_scale], axis=1)[:, nominal.scale_column]
    is_root = np.arange(len(nominal.body_mass)) == nominal.root
    com_shift = xp.where(is_root[:, None], params.com_offset[:, None, :], 0.0)
    is_ground_or_foot = np.isin(np.arange(len(nominal.geom_friction)), nominal.friction_geoms)
    sliding = xp.where(is_ground_or_foot, contact_friction(params.friction), nominal.geom_friction[:, 0])
    strength = params.motor_strength
    kp = nominal.gain * strength * params.kp_scale
    kd = nominal.damping * strength * params.kd_scale
    rest = (*kp.shape, 9)
    gainprm = xp.concatenate([kp[..., None], xp.broadcast_to(nominal.gainprm[:, 1:], rest)], axis=-1)
    biasprm = xp.concatenate(
        [
            xp.broadcast_to(nominal.biasprm[:, :1], (*kp.shape, 1)),
            -kp[..., None],
            -kd[..., None],
            xp.broadcast_to(nominal.biasprm[:, 3:], (*kp.shape, 7)),
        ],
        axis=-1,
    )
    return {
        "body_mass": nominal.body_mass * mass_scale,
        "body_inertia": nominal.body_inertia * mass_scale[..., None],
        "body_ipos": nominal.body_ipos + com_shift,
        "geom_friction": xp.concatenate(
            [sliding[..., None], xp.broadcast_to(nominal.geom_friction[:, 1:], (*sliding.shape, 2))], axis=-1
        ),
        "actuator_gainprm": gainprm,
        "actuator_biasprm": biasprm,
        "actuator_forcerange": nominal.forcerange * strength[:, :, None],
    }


def apply_domain(models: list[mujoco.MjModel], nominal: NominalModel, params: DomainParams) -> None:
    """Write robot k's domain parameters (row k of `params`) into `models[k]`, from the nominal values."""
    fields = domain_model_fields(nominal, params)
    for k, model in enumerate(models):
        for name, values in fields.items():
            getattr(model, name)[:] = values[k]


def lowest_sole_clearance(sole_xpos: np.ndarray, sole_radius: np.ndarray, terrain: Terrain) -> np.ndarray:
    """Height (n,) of each robot's lowest sole sphere above the ground under its centre.

    `sole_xpos` (n, spheres, 3): the sole spheres' world positions (numpy or JAX); `sole_radius`: their radii.
    """
    xp = namespace(sole_xpos)
    clearance = sole_xpos[..., 2] - sole_radius - terrain.height_at(sole_xpos[..., :2])
    return xp.min(clearance, axis=1)


def reset_states(
    models: list[mujoco.MjModel],
    datas: list[mujoco.MjData],
    qpos: np.ndarray,
    terrain: Terrain,
    nominal: NominalModel,
) -> None:
    """Set robot k at rest at `qpos[k]`, lowered so its lowest sole sphere just clears the ground."""
    soles = nominal.sole_geoms
    for model, data, q in zip(models, datas, qpos, strict=True):
        mujoco.mj_resetData(model, data)
        data.qpos[:] = q
        data.ctrl[:] = nominal.default_ctrl
        mujoco.mj_kinematics(model, data)
    lowest = lowest_sole_clearance(
        np.array([data.geom_xpos[soles] for data in datas]), nominal.sole_radius, terrain
    )
    for model, data, q, low in zip(models, datas, qpos, lowest.tolist(), strict=True):
        data.qpos[2] = q[2] - low + GROUND_CLEARANCE
        mujoco.mj_forward(model, data)
