"""The robot-IO seam: RobotState checks, MujocoRobot behind it, the env driving a RobotIO."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from langenv.env import LangCtrlEnv
from langenv.errors import ConfigError, DeviceError
from langenv.live.ring import AudioRing
from langenv.robot.backends import ROBOT_BACKENDS, make_robot
from langenv.robot.io import RobotIO, RobotState
from langenv.robot.sim_io import MujocoRobot
from langenv.users import load_session
from langenv.users.session_csv import write_session


def test_robot_state_is_checked_and_read_only() -> None:
    z = np.zeros(6)
    s = RobotState(0.0, z, z, z, z)
    assert not s.tcp_pose.flags.writeable
    with pytest.raises(DeviceError, match="wrench"):
        RobotState(0.0, z, z, z, np.zeros(3))
    with pytest.raises(DeviceError, match="tcp_velocity"):
        RobotState(0.0, z, np.full(6, np.nan), z, z)


def test_backends_by_name() -> None:
    assert set(ROBOT_BACKENDS) == {"mujoco", "ur", "ur-fake"}
    with pytest.raises(ConfigError, match="known: mujoco, ur, ur-fake"):
        make_robot("kuka")
    robot = make_robot("mujoco")
    assert isinstance(robot, RobotIO)


def test_mujoco_robot_through_the_seam_runs_the_simulated_episode() -> None:
    """Without a person, the env over MujocoRobot repeats the env's own episode (to a tick)."""
    zero = np.zeros(3)
    direct = LangCtrlEnv(decision_hz=500, users=lambda t, v, tan: zero)
    seam = LangCtrlEnv(decision_hz=500, robot=MujocoRobot(ft_noise=0.05))
    ends = []
    for env in (direct, seam):
        env.reset(seed=0)
        action = np.zeros(env.action_space.shape, np.float32)
        for _ in range(20000):
            _, _, term, trunc, info = env.step(action)
            if term or trunc:
                break
        assert info["safety_stop"] is None
        ends.append((info["t_motion"], info["am"]))
    assert ends[1][0] == pytest.approx(ends[0][0], abs=0.0021)
    assert ends[1][1] == pytest.approx(ends[0][1], abs=0.0021)


def test_mujoco_robot_stop_latches() -> None:
    robot = MujocoRobot()
    assert not robot.write_speed(np.array([0.1, 0, 0, 0, 0, 0.0]), 1.0, 0.002).any()
    robot.enable()
    sent = robot.write_speed(np.array([3.0, 0, 0, 0, 0, 0.0]), 1.0, 0.002)
    assert np.linalg.norm(sent[:3]) == pytest.approx(0.5)  # the robot-side speed clip
    robot.stop()
    assert not robot.write_speed(np.array([0.1, 0, 0, 0, 0, 0.0]), 1.0, 0.002).any()


def test_ring_fades_out() -> None:
    ring = AudioRing(100)
    ring.write(np.ones(80, np.float32))
    ring.fade_out(10)
    out = np.empty(20, np.float32)
    assert ring.read_into(out) == 10
    assert out[0] == 1.0 and out[9] == 0.0 and np.all(np.diff(out[:10]) < 0)


def test_write_session_round_trip(tmp_path: Path) -> None:
    path = write_session(
        tmp_path / "s.csv", {"t": [0.0, 0.02], "cooperation": [1.0, 0.5], "phrase": ["a", ""]}
    )
    s = load_session(path)
    assert s.cooperation.tolist() == [1.0, 0.5]


@pytest.mark.parametrize("robot", ["mujoco", "ur-fake"])
def test_play_runs_a_session_through_the_seam(tmp_path: Path, robot: str, capsys) -> None:
    """Real time on a shared machine may end it early on a late period: a named stop, still
    logged; either way the loop ran on the robot and said how it ended."""
    from langctrl.jobs.play import main

    wav, log = tmp_path / "a.wav", tmp_path / "s.csv"
    argv = ["--robot", robot, "--headless", "--seconds", "0.5", "--audio-out", str(wav)]
    assert main([*argv, "--log-out", str(log)]) == 0
    out = capsys.readouterr().out
    assert f"play: lc on {robot}, user synthetic:" in out and "periods" in out
    assert wav.exists()


def test_limit_speed_properties() -> None:
    from hypothesis import given
    from hypothesis import strategies as st

    from langenv.robot.io import limit_speed

    finite = st.floats(-10.0, 10.0, allow_nan=False)

    @given(st.lists(finite, min_size=6, max_size=6), st.floats(0.01, 2.0))
    def check(xd: list[float], vmax: float) -> None:
        out = limit_speed(np.array(xd), vmax)
        assert np.linalg.norm(out[:3]) <= vmax * (1 + 1e-12)
        if np.linalg.norm(xd[:3]) <= vmax:
            assert out.tolist() == xd  # within the limit: unchanged
        else:  # scaled along the same direction
            assert np.allclose(np.cross(out[:3], xd[:3]), 0.0, atol=1e-9)
        assert out[3:].tolist() == xd[3:]

    check()
    assert not limit_speed(np.array([np.nan, 0, 0, 0, 0, 0.0]), 0.5).any()


def test_a_robot_env_refuses_a_simulated_user() -> None:
    env = LangCtrlEnv(robot=MujocoRobot())
    with pytest.raises(ConfigError, match="the person is real"):
        env.reset(seed=0, options={"user": "synthetic"})


def test_play_on_a_robot_runs_the_chosen_exercise(tmp_path: Path, capsys) -> None:
    """--exercise with --robot: the session starts at that exercise's start (it ran the study's)."""
    import csv

    from langctrl.jobs.play import main
    from langenv.exercise import resolve_exercise

    wav, log = tmp_path / "a.wav", tmp_path / "s.csv"
    argv = ["--robot", "ur-fake", "--headless", "--seconds", "0.3", "--audio-out", str(wav)]
    assert main([*argv, "--log-out", str(log), "--exercise", "hand_to_mouth"]) == 0
    first = next(csv.DictReader(log.open()))
    xyz = [float(first[k]) for k in ("x", "y", "z")]
    np.testing.assert_allclose(xyz, resolve_exercise("hand_to_mouth").start, atol=1e-3)
    capsys.readouterr()
