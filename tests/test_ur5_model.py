"""Our UR5 MJCF against the manufacturer's published kinematics and masses."""

from __future__ import annotations

import math

import mujoco
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from langenv.robot.arm import UR5_JOINTS, UR5_XML

# Universal Robots, UR5 (CB3) DH parameters, masses and centres of mass (DH frame of each link).
DH_D = (0.089159, 0.0, 0.0, 0.10915, 0.09465, 0.0823)
DH_A = (0.0, -0.425, -0.39225, 0.0, 0.0, 0.0)
DH_ALPHA = (math.pi / 2, 0.0, 0.0, math.pi / 2, -math.pi / 2, 0.0)
MASSES = (3.7, 8.393, 2.275, 1.219, 1.219, 0.1879)
COMS = (
    (0.0, -0.02561, 0.00193),
    (0.2125, 0.0, 0.11336),
    (0.15, 0.0, 0.0265),
    (0.0, -0.0018, 0.01634),
    (0.0, 0.0018, 0.01634),
    (0.0, 0.0, -0.001159),
)
LINKS = (
    "shoulder_link",
    "upper_arm_link",
    "forearm_link",
    "wrist_1_link",
    "wrist_2_link",
    "wrist_3_link",
)
EXERCISE_START = np.array([-0.350, -0.6206, 0.04])


def dh_frames(q: np.ndarray) -> list[np.ndarray]:
    """Standard DH: the 4x4 poses of frames 1..6 in the base frame."""
    t = np.eye(4)
    frames = []
    for i in range(6):
        ct, st_ = math.cos(q[i]), math.sin(q[i])
        ca, sa = math.cos(DH_ALPHA[i]), math.sin(DH_ALPHA[i])
        a_i = np.array(
            [
                [ct, -st_ * ca, st_ * sa, DH_A[i] * ct],
                [st_, ct * ca, -ct * sa, DH_A[i] * st_],
                [0.0, sa, ca, DH_D[i]],
                [0.0, 0.0, 0.0, 1.0],
            ]
        )
        t = t @ a_i
        frames.append(t.copy())
    return frames


@pytest.fixture(scope="module")
def model() -> mujoco.MjModel:
    return mujoco.MjModel.from_xml_path(str(UR5_XML))


def test_loads_standalone_with_required_options(model: mujoco.MjModel) -> None:
    assert model.opt.timestep == pytest.approx(0.002)
    assert model.opt.integrator == mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    assert model.nq == model.nv == 6
    for name in UR5_JOINTS:
        j = model.joint(name)
        assert j.type[0] == mujoco.mjtJoint.mjJNT_HINGE
        assert j.limited[0]
        np.testing.assert_allclose(j.range, [-2 * math.pi, 2 * math.pi], rtol=1e-9)
        assert model.dof_armature[j.dofadr[0]] > 0.0
    assert mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, "handle") >= 0
    assert mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_CAMERA, "overview") >= 0


def test_published_masses_and_gravcomp(model: mujoco.MjModel) -> None:
    for link, mass in zip(LINKS, MASSES, strict=True):
        body = model.body(link)
        assert body.mass[0] == pytest.approx(mass, abs=1e-9)
        assert model.body_gravcomp[body.id] == 1.0
        # a physical inertia: positive, satisfying the triangle inequality
        i = np.sort(body.inertia)
        assert i[0] > 0 and i[0] + i[1] >= i[2]
    assert model.body_gravcomp[model.body("handle_link").id] == 1.0


@settings(max_examples=25, deadline=None)
@given(st.lists(st.floats(-2 * math.pi, 2 * math.pi), min_size=6, max_size=6))
def test_forward_kinematics_and_coms_match_dh(q: list[float]) -> None:
    m = mujoco.MjModel.from_xml_path(str(UR5_XML))
    d = mujoco.MjData(m)
    d.qpos[:] = q
    mujoco.mj_kinematics(m, d)
    frames = dh_frames(np.asarray(q))
    flange = m.site("flange").id
    np.testing.assert_allclose(d.site_xpos[flange], frames[5][:3, 3], atol=1e-9)
    np.testing.assert_allclose(d.site_xmat[flange].reshape(3, 3), frames[5][:3, :3], atol=1e-9)
    for link, com, frame in zip(LINKS, COMS, frames, strict=True):
        expected = frame[:3, :3] @ np.asarray(com) + frame[:3, 3]
        np.testing.assert_allclose(d.xipos[m.body(link).id], expected, atol=1e-5)


def test_home_keyframe_at_exercise_start_tool_down_elbow_up(model: mujoco.MjModel) -> None:
    d = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, d, model.key("home").id)
    mujoco.mj_forward(model, d)
    handle = model.site("handle").id
    assert np.linalg.norm(d.site_xpos[handle] - EXERCISE_START) < 1e-3
    tool_axis = d.site_xmat[handle].reshape(3, 3)[:, 2]
    assert tool_axis @ np.array([0.0, 0.0, -1.0]) > math.cos(math.radians(1.0))
    shoulder = d.xpos[model.body("upper_arm_link").id]
    elbow = d.xpos[model.body("forearm_link").id]
    wrist = d.xpos[model.body("wrist_1_link").id]
    assert elbow[2] > max(shoulder[2], wrist[2]) + 0.1
    assert d.ncon == 0


def test_table_below_handle_path_and_collision_filter(model: mujoco.MjModel) -> None:
    table = model.geom("table")
    top = table.pos[2] + table.size[2]
    assert -0.02 < top < EXERCISE_START[2] - 0.02

    def collide(g1: int, g2: int) -> bool:
        return bool(
            (model.geom_contype[g1] & model.geom_conaffinity[g2])
            or (model.geom_contype[g2] & model.geom_conaffinity[g1])
        )

    arm_bodies = {model.body(name).id for name in (*LINKS, "handle_link")}
    arm_geoms = [g for g in range(model.ngeom) if model.geom_bodyid[g] in arm_bodies]
    colliding = [g for g in arm_geoms if collide(g, table.id)]
    primitives = {
        int(t)
        for t in (
            mujoco.mjtGeom.mjGEOM_CAPSULE,
            mujoco.mjtGeom.mjGEOM_SPHERE,
            mujoco.mjtGeom.mjGEOM_CYLINDER,
            mujoco.mjtGeom.mjGEOM_BOX,
        )
    }
    assert len(colliding) >= 5  # upper arm, forearm, wrists, handle
    for g in colliding:
        assert int(model.geom_type[g]) in primitives
    for i, g1 in enumerate(arm_geoms):
        for g2 in arm_geoms[i + 1 :]:
            assert not collide(g1, g2), (model.geom(g1).name, model.geom(g2).name)


def test_overview_camera_sees_arm_and_exercise(model: mujoco.MjModel) -> None:
    d = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, d, model.key("home").id)
    mujoco.mj_forward(model, d)
    cam = model.camera("overview").id
    pos, rot = d.cam_xpos[cam], d.cam_xmat[cam].reshape(3, 3)
    half = math.radians(model.cam_fovy[cam]) / 2
    # default offscreen aspect is irrelevant: check inside the vertical FOV and a 4:3 horizontal
    points = [
        EXERCISE_START,
        np.array([-0.596, -0.567, 0.04]),
        np.array([-0.127, -0.503, 0.04]),
        np.zeros(3),
        d.xpos[model.body("forearm_link").id],
    ]
    for p in points:
        local = rot.T @ (p - pos)
        assert local[2] < 0  # in front of the camera (it looks along -z)
        depth = -local[2]
        assert abs(local[1] / depth) < math.tan(half) * 0.95
        assert abs(local[0] / depth) < math.tan(half) * 4 / 3 * 0.95
