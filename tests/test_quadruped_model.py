"""The Go2-like quadruped model (go2like/go2like.xml): spec against its constants, standing, drop, push."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from zerith_gym.core.spec import read_sensors
from zerith_gym.go2like import constants as quad


@pytest.fixture(scope="module")
def model() -> mujoco.MjModel:
    return mujoco.MjModel.from_xml_path(str(quad.ASSET_PATH))


def _home(model: mujoco.MjModel) -> mujoco.MjData:
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, model.key(quad.HOME_KEYFRAME).id)
    mujoco.mj_forward(model, data)
    return data


def _roll_pitch(model: mujoco.MjModel, data: mujoco.MjData) -> np.ndarray:
    rot = data.xmat[model.body(quad.ROOT_BODY).id].reshape(3, 3)
    return np.array([np.arctan2(rot[2, 1], rot[2, 2]), -np.arcsin(rot[2, 0])])


def _trunk_height(model: mujoco.MjModel, data: mujoco.MjData) -> float:
    return float(data.xpos[model.body(quad.ROOT_BODY).id][2])


def _ground_contacts(model: mujoco.MjModel, data: mujoco.MjData) -> set[str]:
    """Names of the geoms touching the floor; AssertionError if any of them is not a foot."""
    floor = model.geom("floor").id
    touching = set()
    for contact in data.contact[: data.ncon]:
        if floor in (contact.geom1, contact.geom2):
            other = contact.geom2 if contact.geom1 == floor else contact.geom1
            touching.add(model.geom(other).name)
    assert touching <= set(quad.FOOT_GEOMS), f"not feet on the ground: {touching - set(quad.FOOT_GEOMS)}"
    return touching


def _simulate(
    model: mujoco.MjModel, data: mujoco.MjData, seconds: float, push: np.ndarray | None = None
) -> dict[str, np.ndarray]:
    """Step with the default pose commanded; per step, the trunk's height, |roll|/|pitch| and position."""
    data.ctrl[:] = quad.DEFAULT_JOINT_POS
    root = model.body(quad.ROOT_BODY).id
    if push is not None:
        data.xfrc_applied[root, :3] = push
    heights, tilts, positions = [], [], []
    for _ in range(round(seconds / model.opt.timestep)):
        mujoco.mj_step(model, data)
        heights.append(_trunk_height(model, data))
        tilts.append(np.abs(_roll_pitch(model, data)).max())
        positions.append(data.xpos[root].copy())
    data.xfrc_applied[root] = 0.0
    return {"height": np.array(heights), "tilt": np.array(tilts), "pos": np.array(positions)}


def _assert_standing(model: mujoco.MjModel, data: mujoco.MjData) -> None:
    assert abs(_trunk_height(model, data) - quad.STANDING_HEIGHT) < 0.03
    assert np.abs(_roll_pitch(model, data)).max() < 0.05
    assert _ground_contacts(model, data) == set(quad.FOOT_GEOMS)
    # At rest: the fore-aft sway of the trunk on its compliant (kp 20) legs has died down.
    assert np.linalg.norm(data.qvel[:3]) < 0.05 and np.linalg.norm(data.qvel[3:6]) < 0.1


def test_joints_actuators_and_timing_match_the_module(model: mujoco.MjModel) -> None:
    hinges = [j for j in range(model.njnt) if model.jnt_type[j] == mujoco.mjtJoint.mjJNT_HINGE]
    assert [model.joint(j).name for j in hinges] == list(quad.JOINT_NAMES)
    assert model.nq == 7 + quad.NUM_JOINTS and model.nu == quad.NUM_JOINTS
    np.testing.assert_allclose(model.jnt_range[hinges], quad.JOINT_RANGE)
    for j, name in zip(hinges, quad.JOINT_NAMES, strict=True):
        axis = [1.0, 0.0, 0.0] if name.endswith("_hip") else [0.0, 1.0, 0.0]
        np.testing.assert_array_equal(model.jnt_axis[j], axis)
    assert [model.actuator(i).name for i in range(model.nu)] == list(quad.JOINT_NAMES)
    np.testing.assert_array_equal(model.actuator_trnid[:, 0], hinges)
    np.testing.assert_allclose(model.actuator_gainprm[:, 0], quad.KP)
    np.testing.assert_allclose(-model.actuator_biasprm[:, 1], quad.KP)
    np.testing.assert_allclose(-model.actuator_biasprm[:, 2], quad.KD)
    torque_range = np.stack([-quad.TORQUE_LIMIT, quad.TORQUE_LIMIT], axis=1)
    np.testing.assert_allclose(model.actuator_forcerange, torque_range)
    np.testing.assert_allclose(model.actuator_ctrlrange, quad.JOINT_RANGE)
    assert np.all(model.actuator_forcelimited) and np.all(model.actuator_ctrllimited)
    assert model.opt.timestep == quad.PHYSICS_DT
    assert quad.DECIMATION == 4 and abs(quad.DECIMATION * quad.PHYSICS_DT - quad.CONTROL_DT) < 1e-12
    assert np.all(quad.ACTION_SCALE == 0.25)
    layout = quad.GO2LIKE.sensor_layout(model)
    assert layout.foot_force.stop - layout.foot_pos.start == 3 * 3 * len(quad.LEGS)


def test_masses_and_geometry_follow_the_published_figures(model: mujoco.MjModel) -> None:
    root = model.body(quad.ROOT_BODY).id
    assert model.jnt_type[model.body_jntadr[root]] == mujoco.mjtJoint.mjJNT_FREE
    assert model.body_subtreemass[root] == pytest.approx(quad.TOTAL_MASS, abs=1e-6)
    assert abs(quad.TOTAL_MASS - 15.0) <= 0.3
    assert np.all(model.body_inertia[1:] > 0)
    hips = np.array([model.body(f"{leg}_hip").pos for leg in quad.LEGS])
    np.testing.assert_allclose(hips[:, 0], [0.1934, 0.1934, -0.1934, -0.1934])
    np.testing.assert_allclose(hips[:, 1], [0.0465, -0.0465, 0.0465, -0.0465])
    assert hips[0, 0] - hips[2, 0] == pytest.approx(quad.HIP_LENGTH)
    assert hips[0, 1] - hips[1, 1] == pytest.approx(quad.HIP_WIDTH)
    for leg, side in zip(quad.LEGS, (1, -1, 1, -1), strict=True):
        np.testing.assert_allclose(model.body(f"{leg}_thigh").pos, [0, side * 0.0955, 0])
        np.testing.assert_allclose(model.body(f"{leg}_calf").pos, [0, 0, -0.213])
        np.testing.assert_allclose(model.body(f"{leg}_foot").pos, [0, 0, -0.213])
    # Mirror images: right legs are the left ones reflected in the x-z plane.
    for left, right in (("FL", "FR"), ("RL", "RR")):
        for part in ("hip", "thigh", "calf", "foot"):
            a, b = model.body(f"{left}_{part}"), model.body(f"{right}_{part}")
            np.testing.assert_allclose(b.ipos, a.ipos * [1, -1, 1])
            np.testing.assert_allclose(b.mass, a.mass)


def test_only_the_ground_touches_the_feet_trunk_thighs_and_calves(model: mujoco.MjModel) -> None:
    colliding = {
        model.geom(g).name for g in range(model.ngeom) if model.geom_contype[g] or model.geom_conaffinity[g]
    }
    links = {f"{leg}_{link}" for leg in quad.LEGS for link in ("thigh", "calf")}
    assert colliding == {"floor", "trunk", *quad.FOOT_GEOMS, *links}
    feet = [model.geom(name) for name in quad.FOOT_GEOMS]
    for foot in feet:
        assert foot.type == mujoco.mjtGeom.mjGEOM_SPHERE and foot.size[0] == quad.FOOT_RADIUS
        assert model.body(int(foot.bodyid[0])).name in quad.FOOT_BODIES
    # No two geoms of the robot collide with each other: only the ground starts contacts.
    robot_geoms = [model.geom(name) for name in colliding - {"floor"}]
    assert not any(
        a.contype & b.conaffinity or b.contype & a.conaffinity for a in robot_geoms for b in robot_geoms
    )


def test_a_fallen_robot_lies_on_its_trunk_and_the_contact_sensors_see_it(model: mujoco.MjModel) -> None:
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, model.key(quad.HOME_KEYFRAME).id)
    data.qpos[3:7] = [0.0, 1.0, 0.0, 0.0]  # upside down: legs up, the trunk 0.2645 m above the floor
    data.ctrl[:] = quad.DEFAULT_JOINT_POS
    for _ in range(400):
        mujoco.mj_step(model, data)
    readings = read_sensors(quad.GO2LIKE.sensor_layout(model), data.sensordata[None])
    assert readings.base_contact[0, 0] > 0
    assert np.all(readings.foot_force[0] == 0.0)  # the feet are in the air
    home = _home(model)
    standing = read_sensors(quad.GO2LIKE.sensor_layout(model), home.sensordata[None])
    assert standing.base_contact[0, 0] == 0 and not standing.leg_contact.any()


def test_home_keyframe_stands_on_the_floor_with_knees_pointing_backward(model: mujoco.MjModel) -> None:
    data = _home(model)
    np.testing.assert_array_equal(data.ctrl, quad.DEFAULT_JOINT_POS)
    assert np.abs(data.qpos[7:] - quad.DEFAULT_JOINT_POS).max() < 0.4  # bent by the weight, see the MJCF
    assert _trunk_height(model, data) == pytest.approx(quad.STANDING_HEIGHT)
    feet = np.array([data.geom_xpos[model.geom(name).id] for name in quad.FOOT_GEOMS])
    np.testing.assert_allclose(feet[:, 2] - quad.FOOT_RADIUS, 0.0, atol=0.002)
    assert feet[0, 1] - feet[1, 1] == pytest.approx(quad.STANCE_WIDTH, abs=0.01)
    for leg in quad.LEGS:
        thigh, knee, foot = (data.xpos[model.body(f"{leg}_{part}").id] for part in ("thigh", "calf", "foot"))
        assert knee[0] < thigh[0] - 0.1 and knee[0] < foot[0] - 0.1  # knee behind hip and foot
        assert thigh[2] > knee[2] > foot[2]


def test_home_stance_holds_for_2_seconds(model: mujoco.MjModel) -> None:
    data = _home(model)
    start = _trunk_height(model, data)
    run = _simulate(model, data, 2.0)
    assert np.abs(run["height"] - start).max() < 0.03
    assert run["tilt"].max() < 0.05
    assert np.linalg.norm(run["pos"][-1, :2] - run["pos"][0, :2]) < 0.02
    _assert_standing(model, data)
    reaction = quad.GO2LIKE.sensor_layout(model).foot_force
    weight = model.body_subtreemass[model.body(quad.ROOT_BODY).id] * 9.81
    assert data.sensordata[reaction].reshape(4, 3)[:, 2].sum() == pytest.approx(weight, rel=0.02)


def test_dropped_from_10_cm_higher_it_settles_to_standing(model: mujoco.MjModel) -> None:
    data = _home(model)
    data.qpos[2] += 0.1
    mujoco.mj_forward(model, data)
    assert not _ground_contacts(model, data)
    run = _simulate(model, data, 4.0)
    assert run["tilt"].max() < 0.3
    _assert_standing(model, data)


def test_the_default_pose_settles_to_the_home_stance(model: mujoco.MjModel) -> None:
    """Started in the default pose with the feet on the floor, kp 20 lets the weight lower the trunk 6 cm."""
    data = mujoco.MjData(model)
    data.qpos[:7] = [0, 0, 1, 1, 0, 0, 0]
    data.qpos[7:] = quad.DEFAULT_JOINT_POS
    mujoco.mj_kinematics(model, data)
    lowest = min(data.geom_xpos[model.geom(name).id][2] for name in quad.FOOT_GEOMS) - quad.FOOT_RADIUS
    data.qpos[2] -= lowest
    mujoco.mj_forward(model, data)
    assert _trunk_height(model, data) == pytest.approx(0.32, abs=0.005)
    _simulate(model, data, 4.0)
    _assert_standing(model, data)
    np.testing.assert_allclose(data.qpos[7:], _home(model).qpos[7:], atol=0.05)


def test_a_20_newton_sideways_push_does_not_topple_it(model: mujoco.MjModel) -> None:
    data = _home(model)
    push = _simulate(model, data, 0.2, push=np.array([0.0, 20.0, 0.0]))
    after = _simulate(model, data, 2.5)
    displacement = np.concatenate([push["pos"], after["pos"]])[:, 1] - push["pos"][0, 1]
    assert displacement.max() > 0.005  # the push moved the trunk sideways
    assert max(push["tilt"].max(), after["tilt"].max()) < 0.2
    _assert_standing(model, data)
