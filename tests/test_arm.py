"""Arm: reset/IK, the velocity controller C, limits, F_ext, other MJCFs, rendering."""

from __future__ import annotations

import math
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import mujoco
import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from langenv.errors import ActionError, ConfigError
from langenv.robot import UR5_JOINTS, Arm

START = np.array([-0.350, -0.6206, 0.04])
ARC_ENDS = (np.array([-0.596, -0.567, 0.04]), np.array([-0.127, -0.503, 0.04]))

TOY_XML = """
<mujoco model="toy2">
  <compiler angle="radian"/>
  <option timestep="0.002" integrator="implicitfast" gravity="0 0 0"/>
  <worldbody>
    <body name="l1">
      <joint name="j1" type="hinge" axis="0 0 1" range="-1.0 1.0" armature="0.01"/>
      <geom type="capsule" fromto="0 0 0 0.3 0 0" size="0.02" mass="1"/>
      <body name="l2" pos="0.3 0 0">
        <joint name="j2" type="hinge" axis="0 0 1" range="0.2 2.5" armature="0.01"/>
        <geom type="capsule" fromto="0 0 0 0.25 0 0" size="0.02" mass="0.5"/>
        <site name="tip" pos="0.25 0 0"/>
      </body>
    </body>
  </worldbody>
  <actuator>
    <velocity name="a1" joint="j1" kv="20"/>
    <velocity name="a2" joint="j2" kv="10"/>
    {extra}
  </actuator>
  <keyframe><key name="rest" qpos="0 1.2"/></keyframe>
</mujoco>
"""


def toy_path(tmp_path: Path, extra: str = "") -> Path:
    path = tmp_path / "toy2.xml"
    path.write_text(TOY_XML.replace("{extra}", extra))
    return path


@pytest.fixture(scope="module")
def ur5() -> Arm:
    return Arm()


def run(arm: Arm, v: np.ndarray, f: np.ndarray, steps: int) -> None:
    for _ in range(steps):
        arm.step(v, f)


def test_finds_ur5_joints_and_actuators_by_name(ur5: Arm) -> None:
    assert ur5.joint_names == UR5_JOINTS
    assert ur5.actuator_names == UR5_JOINTS
    assert ur5.dt == pytest.approx(0.002)


@pytest.mark.parametrize("target", [START, *ARC_ENDS, START + np.array([0.05, 0.05, 0.1])])
def test_reset_puts_handle_at_target_with_home_orientation(ur5: Arm, target: np.ndarray) -> None:
    ur5.reset()
    home_rot = ur5.hand_rotation()
    ur5.reset(target)
    assert np.linalg.norm(ur5.hand_position() - target) < 1e-3
    assert ur5.orientation_error() < 1e-6
    np.testing.assert_allclose(ur5.hand_rotation(), home_rot, atol=1e-6)
    np.testing.assert_array_equal(ur5.data.qvel, 0.0)
    np.testing.assert_allclose(ur5.hand_velocity(), 0.0)


def test_reset_rejects_unreachable_contact_and_bad_input(ur5: Arm) -> None:
    with pytest.raises(ConfigError, match="hand_position"):
        ur5.reset(np.array([1.5, 0.0, 0.04]))
    with pytest.raises(ConfigError, match="contact"):
        ur5.reset(np.array([-0.35, -0.62, -0.02]))  # the grip would be inside the table
    with pytest.raises(ConfigError, match="hand_position"):
        ur5.reset(np.array([np.nan, 0.0, 0.0]))
    with pytest.raises(ConfigError, match="hand_position"):
        ur5.reset(np.zeros(2))


def test_tracks_constant_velocity_holding_orientation(ur5: Arm) -> None:
    ur5.reset(START)
    v = np.array([0.08, 0.09, 0.0])  # 0.12 m/s, the guided speed
    x0 = ur5.hand_position()
    worst_angle = 0.0
    for k in range(1, 601):
        ur5.step(v, np.zeros(3))
        worst_angle = max(worst_angle, ur5.orientation_error())
        if k > 100:  # after 0.2 s
            assert np.linalg.norm(ur5.hand_velocity() - v) < 2e-3
    assert worst_angle < math.radians(1.0)
    travelled = ur5.hand_position() - x0
    np.testing.assert_allclose(travelled, v * 600 * ur5.dt, atol=2e-3)


def test_hand_velocity_matches_finite_difference(ur5: Arm) -> None:
    ur5.reset(START)
    v = np.array([-0.1, 0.05, 0.02])
    run(ur5, v, np.zeros(3), 100)
    x0 = ur5.hand_position()
    v0 = ur5.hand_velocity()
    ur5.step(v, np.zeros(3))
    v1 = ur5.hand_velocity()
    fd = (ur5.hand_position() - x0) / ur5.dt
    np.testing.assert_allclose(fd, 0.5 * (v0 + v1), atol=2e-4)


def test_hand_speed_limit() -> None:
    arm = Arm(max_hand_speed=0.2)
    arm.reset(START)
    direction = np.array([-0.6, 0.8, 0.0])
    top = 0.0
    for _ in range(250):
        arm.step(5.0 * direction, np.zeros(3))
        vel = arm.hand_velocity()
        top = max(top, float(np.linalg.norm(vel)))
    assert top < 0.2 * 1.02
    assert float(vel @ direction) / np.linalg.norm(vel) > 0.999  # same direction, only slower
    assert np.linalg.norm(vel) > 0.19


def test_joint_speed_limit_scales_uniformly() -> None:
    arm = Arm(max_hand_speed=1.0, max_joint_speed=0.15)
    arm.reset(START)
    direction = np.array([0.0, 1.0, 0.0])
    for _ in range(200):
        arm.step(0.8 * direction, np.zeros(3))
        assert np.max(np.abs(arm.joint_velocities())) < 0.15 * 1.05
    vel = arm.hand_velocity()
    assert float(vel @ direction) / np.linalg.norm(vel) > 0.99
    assert np.linalg.norm(vel) < 0.5  # really slowed down


def test_joint_limit_is_approached_but_not_crossed(tmp_path: Path) -> None:
    arm = Arm(
        toy_path(tmp_path),
        "tip",
        home_keyframe="rest",
        hold_orientation=False,
        joint_limit_margin=0.2,
        position_gain=0.0,
    )
    arm.reset()
    j1 = arm.model.joint("j1").qposadr[0]
    q_max = -np.inf
    for _ in range(1500):
        pos = arm.hand_position()
        tangent = np.array([-pos[1], pos[0], 0.0]) / np.linalg.norm(pos[:2])  # turns j1 up
        arm.step(0.3 * tangent, np.zeros(3))
        q_max = max(q_max, float(arm.data.qpos[j1]))
    assert q_max <= 1.0
    assert q_max > 0.9  # it did go towards the limit
    assert arm.data.nefc == 0  # MuJoCo's own limit constraint never had to act


def test_external_force_pushes_compliant_arm_along_force() -> None:
    arm = Arm(kv_scale=0.0)
    arm.reset(START)
    force = np.array([10.0, -5.0, 0.0])
    run(arm, np.zeros(3), force, 150)
    moved = arm.hand_position() - START
    assert float(moved @ force) / np.linalg.norm(force) > 5e-3
    assert float(moved @ force) / (np.linalg.norm(moved) * np.linalg.norm(force)) > 0.5


def test_external_force_barely_moves_stiff_controller(ur5: Arm) -> None:
    ur5.reset(START)
    force = np.array([10.0, -5.0, 0.0])
    run(ur5, np.zeros(3), force, 500)
    moved = ur5.hand_position() - START
    assert 0.0 < float(moved @ force) / np.linalg.norm(force) < 3e-3
    assert np.linalg.norm(ur5.hand_velocity()) < 1e-3  # settled: no drift


def test_gravity_is_compensated() -> None:
    arm = Arm(kv_scale=0.0)
    arm.reset(START)
    run(arm, np.zeros(3), np.zeros(3), 250)
    assert np.linalg.norm(arm.hand_position() - START) < 1e-4


def test_force_applied_like_mj_applyft(ur5: Arm) -> None:
    ur5.reset(START)
    run(ur5, np.array([0.05, 0.0, 0.0]), np.zeros(3), 20)
    m, d = ur5.model, ur5.data
    force = np.array([3.0, -7.0, 2.0])
    expected = np.zeros(m.nv)
    site = ur5.site_id
    mujoco.mj_applyFT(
        m, d, force, np.zeros(3), d.site_xpos[site].copy(), int(m.site_bodyid[site]), expected
    )
    ur5.step(np.zeros(3), force)
    np.testing.assert_allclose(d.qfrc_applied, expected, atol=1e-12)
    ur5.step(np.zeros(3), np.zeros(3))
    np.testing.assert_array_equal(d.qfrc_applied, 0.0)  # cleared every tick


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
def test_non_finite_inputs_raise_naming_argument(ur5: Arm, bad: float) -> None:
    ur5.reset(START)
    with pytest.raises(ActionError, match="v_ref"):
        ur5.step(np.array([0.0, bad, 0.0]), np.zeros(3))
    with pytest.raises(ActionError, match="f_ext"):
        ur5.step(np.zeros(3), np.array([bad, 0.0, 0.0]))
    with pytest.raises(ActionError, match="v_ref"):
        ur5.step(np.zeros(4), np.zeros(3))
    ur5.step([0.01, 0.0, 0.0], (0.0, 0.0, 0.0))  # type: ignore[arg-type]  # array-likes work


def test_deterministic(ur5: Arm) -> None:
    other = Arm()
    for arm in (ur5, other):
        arm.reset(START)
        run(arm, np.array([0.1, -0.05, 0.0]), np.array([2.0, 1.0, 0.0]), 100)
    np.testing.assert_array_equal(ur5.data.qpos, other.data.qpos)


def test_other_mjcf_with_other_site_name(tmp_path: Path) -> None:
    arm = Arm(toy_path(tmp_path), "tip", home_keyframe="rest", hold_orientation=False)
    assert arm.joint_names == ("j1", "j2")
    target = np.array([0.35, 0.25, 0.0])
    arm.reset(target)
    assert np.linalg.norm(arm.hand_position() - target) < 1e-3
    v = np.array([0.0, 0.1, 0.0])
    run(arm, v, np.zeros(3), 300)
    np.testing.assert_allclose(arm.hand_velocity(), v, atol=5e-3)
    explicit = Arm(
        toy_path(tmp_path),
        "tip",
        joints=["j1", "j2"],
        actuators=["a1", "a2"],
        home_keyframe=None,
        hold_orientation=False,
    )
    assert explicit.actuator_names == ("a1", "a2")


def test_config_errors_name_the_culprit_and_file(tmp_path: Path) -> None:
    path = toy_path(tmp_path)
    with pytest.raises(ConfigError, match=r"'grip'.*toy2\.xml"):
        Arm(path, "grip", home_keyframe=None)
    with pytest.raises(ConfigError, match=r"'j9'.*toy2\.xml"):
        Arm(path, "tip", joints=["j1", "j9"], home_keyframe=None)
    with pytest.raises(ConfigError, match=r"'home'.*toy2\.xml"):
        Arm(path, "tip")
    with pytest.raises(ConfigError, match="model_path"):
        Arm(tmp_path / "missing.xml")
    with pytest.raises(ConfigError, match="max_hand_speed"):
        Arm(max_hand_speed=-1.0)
    with pytest.raises(ConfigError, match="damping"):
        Arm(damping=0.0)
    motor = toy_path(tmp_path, extra='<motor name="m2" joint="j2"/>')
    with pytest.raises(ConfigError, match="velocity actuator"):
        Arm(motor, "tip", joints=["j1", "j2"], actuators=["a1", "m2"], home_keyframe=None)
    bare = tmp_path / "bare.xml"
    bare.write_text(TOY_XML.replace('<velocity name="a2" joint="j2" kv="10"/>', ""))
    with pytest.raises(ConfigError, match=r"'j2'.*bare\.xml"):
        Arm(bare, "tip", home_keyframe=None)


RENDER_SCRIPT = textwrap.dedent(
    """
    import sys
    try:
        import mujoco
        mujoco.Renderer(mujoco.MjModel.from_xml_string("<mujoco/>"), 8, 8).close()
    except Exception as exc:
        print(f"no off-screen OpenGL backend: {exc!r}", file=sys.stderr)
        sys.exit(3)
    import numpy as np
    from langenv.robot import Arm
    arm = Arm()
    arm.reset()
    plain = arm.render(320, 240)
    t = np.linspace(0.0, 1.0, 50)
    path = np.stack([-0.35 - 0.25 * t, -0.62 + 0.05 * t, 0.04 + 0 * t], axis=1)
    drawn = arm.render(320, 240, path=path, force=np.array([-15.0, -5.0, 0.0]))
    arm.close()
    np.savez(sys.argv[1], plain=plain, drawn=drawn)
    """
)


def test_render_offscreen(tmp_path: Path) -> None:
    """Runs in a subprocess so the GL backend is chosen before MuJoCo is first imported."""
    out = tmp_path / "frames.npz"
    env = dict(os.environ)
    env.setdefault("MUJOCO_GL", "egl")
    env["PYTHONPATH"] = os.pathsep.join([str(Path(__file__).parents[1]), env.get("PYTHONPATH", "")])
    proc = subprocess.run(
        [sys.executable, "-c", RENDER_SCRIPT, str(out)],
        env=env,
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )
    if proc.returncode == 3:
        pytest.skip(proc.stderr.strip().splitlines()[-1])
    assert proc.returncode == 0, proc.stderr
    frames = np.load(out)
    plain, drawn = frames["plain"], frames["drawn"]
    assert plain.shape == (240, 320, 3) and plain.dtype == np.uint8
    assert plain.std() > 10  # not a blank frame
    assert np.mean(np.any(plain != drawn, axis=2)) > 0.002  # path and arrow were drawn


@given(
    st.lists(st.sampled_from([0.0, -0.0, 1.0, -0.5, 0.3, 2.5e-3, -7.1]), min_size=9, max_size=9),
    st.floats(0.01, 100.0),
)
def test_rotation_error_matrix_is_numpys_cross_to_the_bit(r: list[float], gain: float) -> None:
    """The orientation hold's map equals NumPy's ``cross`` built one, signed zeros included."""
    from langenv.robot.rotation import rotation_error_matrix

    r_held = np.array(r).reshape(3, 3)
    expected = np.zeros((3, 9))
    for a in range(3):
        e_a = np.zeros(3)
        e_a[a] = 1.0
        for i in range(3):
            expected[:, 3 * a + i] = 0.5 * gain * np.cross(e_a, r_held[:, i])
    assert rotation_error_matrix(r_held, gain).tobytes() == expected.tobytes()
