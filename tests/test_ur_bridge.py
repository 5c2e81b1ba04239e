"""The UR bridge run whole against the fake ur-rtde: a session, and each fault -> its named stop.

Only loopback host names are ever used (the fake refuses any other; nothing listens on
127.0.0.1:30004 for the no-robot case).
"""

from __future__ import annotations

import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from langctrl.jobs.robot import main as ur_main
from langenv.errors import ConfigError, DeviceError
from langenv.live.registry import load_registered_policy
from langenv.live.robot_loop import LOG_COLUMNS, RobotLoop
from langenv.live.ur_exercise import exercise_trajectory
from langenv.live.ur_preflight import move_to_start, run_checks, zero_sensor
from langenv.robot.ur import fake_rtde
from langenv.robot.ur.bridge import URRobot
from langenv.robot.ur.config import URConfig, load_ur_config
from langenv.users import load_session

HOST = "127.0.0.1"


def _session(tmp_path: Path, fault: tuple[str, int, dict] | None = None, person=None):
    cfg = URConfig(host=HOST)
    with fake_rtde.FakeUR(HOST, person=person) as ur:
        robot = URRobot(cfg, backend=fake_rtde)
        zero_sensor(robot)
        move_to_start(robot, cfg, lambda q: True)
        if fault is not None:
            ur.inject(fault[0], fault[1], **fault[2])
        loop = RobotLoop(
            robot,
            load_registered_policy("lc"),
            trajectory=exercise_trajectory(cfg),
            log_path=tmp_path / "session.csv",
        )
        report = loop.run()
        robot.close()  # best effort: after a lost link it sends nothing
    return report, ur


def _speed_commands(ur: fake_rtde.FakeUR) -> list[tuple]:
    return [c for c in ur.commands if c[0] in ("speedL", "speedStop", "waitPeriod")]


def _assert_stopped_in_time(ur: fake_rtde.FakeUR) -> None:
    cmds = _speed_commands(ur)
    cmds = cmds[min(i for i, c in enumerate(cmds) if c[0] == "speedL") :]  # the session
    first_stop = min(i for i, c in enumerate(cmds) if c[0] == "speedStop")
    assert all(c[0] != "speedL" for c in cmds[first_stop:]), "speedL after speedStop"
    last_speed = max(i for i, c in enumerate(cmds) if c[0] == "speedL")
    # speedStop in the period that found the fault: one waitPeriod after the last speedL at most
    waits = [c for c in cmds[last_speed:first_stop] if c[0] == "waitPeriod"]
    assert len(waits) <= 1
    assert ur.commands[-1][0] == "stopScript"  # closed: nothing left commanding


def test_whole_session_finishes_and_logs(tmp_path: Path) -> None:
    report, ur = _session(tmp_path)
    assert report.stop is None
    assert report.am is not None and abs(report.am) < 2.0
    assert 9.0 < report.duration_s < 13.0
    _assert_stopped_in_time(ur)
    session = load_session(report.log)
    assert session.duration > 9.0 and session.t_x is not None
    header = report.log.read_text().splitlines()[0].split(",")
    assert tuple(header) == LOG_COLUMNS
    moved = ur.pose[:3] - exercise_trajectory(URConfig(host=HOST)).position(0.0)
    assert np.linalg.norm(moved) > 0.05  # the arm went along the exercise


FAULTS = [
    ("late", 1000, {"extra": 0.01}, "late_period"),
    ("protective_stop", 1000, {}, "robot_protective_stop"),
    ("emergency_stop", 1000, {}, "emergency_stop"),
    ("program_stop", 1000, {}, "program_stopped"),
    ("force_spike", 1000, {"force": (0.0, 0.0, 300.0)}, "force"),
    ("stuck_sensor", 1000, {}, "sensor_stuck"),
    ("joint_limit", 1000, {"joint": 0, "margin": 0.005}, "joint_limit"),
    ("stale_state", 1000, {}, "connection_lost"),
]


@pytest.mark.parametrize(("kind", "at", "params", "stop"), FAULTS, ids=[f[0] for f in FAULTS])
def test_each_fault_is_its_named_stop(tmp_path: Path, kind, at, params, stop) -> None:
    report, ur = _session(tmp_path, (kind, at, params))
    assert report.stop is not None and report.stop.limit == stop, report.summary()
    assert report.am is None
    assert 1.9 < report.duration_s < 2.6
    _assert_stopped_in_time(ur)
    assert load_session(report.log).duration > 1.5


def test_lost_connection_is_a_named_stop(tmp_path: Path) -> None:
    report, ur = _session(tmp_path, ("disconnect", 1000, {}))
    assert report.stop is not None and report.stop.limit == "connection_lost"
    speeds = [c for c in ur.commands if c[0] == "speedL"]
    assert len(speeds) == 1000  # the 1001st never reached the robot
    assert load_session(report.log).duration > 1.5


def test_a_dead_receive_link_stops_at_once(tmp_path: Path) -> None:
    """ur-rtde's receive thread dies on a socket error and its getters go on returning the last
    state without raising: the bridge sees isConnected() False in the next read, not 10 stale
    periods later."""
    report, ur = _session(tmp_path, ("receive_lost", 1000, {}))
    assert report.stop is not None and report.stop.limit == "connection_lost", report.summary()
    assert ur.speedl_count == 1001  # the one that met the loss, and none after
    _assert_stopped_in_time(ur)


def test_ctrl_c_is_the_interrupted_stop(tmp_path: Path) -> None:
    def person(t: float, v: np.ndarray) -> np.ndarray:
        if t > 3.0:
            raise KeyboardInterrupt
        return np.zeros(3)

    report, ur = _session(tmp_path, person=person)
    assert report.stop is not None and report.stop.limit == "interrupted"
    cmds = [c for c in _speed_commands(ur) if c[0] != "waitPeriod"]
    assert cmds[-1][0] == "speedStop"


@pytest.mark.slow
def test_eval_compare_reads_the_robot_session(tmp_path: Path) -> None:
    from eval.compare import main as compare

    _session(tmp_path)
    out = tmp_path / "out"
    rc = compare(["--policies", "lc", "--sessions", str(tmp_path), "--out", str(out)])
    assert rc == 0
    assert "session" in (out / "sessions.csv").read_text()


def test_preflight_flags_a_wrong_payload_and_tcp() -> None:
    cfg = URConfig(host=HOST, payload_mass=1.5)
    with fake_rtde.FakeUR(HOST, tcp_offset=(0, 0, 0.12, 0, 0, 0)):
        robot = URRobot(cfg, backend=fake_rtde)
        checks = {c.name: c.ok for c in run_checks(robot, cfg)}
        robot.close()
    assert checks["payload"] is False and checks["tcp"] is False
    assert checks["controller_version"] and checks["robot_state"] and checks["at_rest"]


def test_old_controller_fails_the_version_check() -> None:
    cfg = URConfig(host=HOST)
    with fake_rtde.FakeUR(HOST, version="URSoftware 3.15.7.106331"):
        robot = URRobot(cfg, backend=fake_rtde)
        checks = {c.name: c.ok for c in run_checks(robot, cfg)}
        robot.close()
    assert checks["controller_version"] is False


def test_unconfirmed_move_moves_nothing() -> None:
    cfg = URConfig(host=HOST)
    with fake_rtde.FakeUR(HOST) as ur:
        robot = URRobot(cfg, backend=fake_rtde)
        with pytest.raises(DeviceError, match="not confirmed"):
            move_to_start(robot, cfg, lambda q: False)
        robot.close()
    assert not [c for c in ur.commands if c[0] in ("moveL", "speedL")]


def test_dry_run_against_the_fake_commands_nothing(
    capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    made: list[fake_rtde.FakeUR] = []
    real_serve = fake_rtde.FakeUR.serve

    def serve(self: fake_rtde.FakeUR) -> fake_rtde.FakeUR:
        made.append(self)
        return real_serve(self)

    monkeypatch.setattr(fake_rtde.FakeUR, "serve", serve)
    assert ur_main(["--host", HOST, "--fake", "--dry-run"]) == 0
    kinds = {c[0] for c in made[0].commands}
    assert kinds <= {"stopScript"}, kinds  # no motion, no speedStop, no zeroing
    assert made[0].speedl_count == 0 and not made[0]._ft_offset.any()
    text = capsys.readouterr().out
    assert "[ok] payload" in text and "would do:" in text and "moveL" in text


def test_no_robot_on_the_host_is_a_named_error(capsys: pytest.CaptureFixture[str]) -> None:
    assert ur_main(["--host", HOST, "--dry-run"]) == 2
    err = capsys.readouterr().err
    assert "no robot answers at 127.0.0.1" in err or ".[ur]" in err


def test_the_reachability_probe_waits_at_most_the_connect_timeout(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """A silent host is given up after config.connect_timeout (its wall time: bench's
    ur_no_answer_s); the refusal names the host, the port and that time."""
    import socket
    import types

    from langenv.errors import DeviceError
    from langenv.robot.ur import bridge
    from langenv.robot.ur.config import URConfig

    asked: list[float] = []

    def silent(address: tuple[str, int], timeout: float) -> None:
        asked.append(timeout)
        raise TimeoutError("timed out")

    monkeypatch.setattr(socket, "create_connection", silent)
    backend = types.SimpleNamespace(probe=bridge._probe)
    with pytest.raises(DeviceError, match=r"no robot answers at 10.0.0.9:30004 within 0.7 s"):
        bridge.URRobot(URConfig(host="10.0.0.9", connect_timeout=0.7), backend=backend)
    assert asked == [0.7]


def test_a_session_without_a_sound_card_is_refused_before_connecting(
    capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    """No PortAudio (or no output device) and no --audio-out: the error comes before the fake
    robot is even served, and no plan is printed."""
    import langenv.live.sinks as sinks
    from langenv.errors import DeviceError

    def no_portaudio() -> object:
        raise DeviceError("live audio needs the PortAudio library (not found)")

    served: list[object] = []
    monkeypatch.setattr(sinks, "_sounddevice", no_portaudio)
    monkeypatch.setattr(fake_rtde.FakeUR, "serve", lambda self: served.append(self) or self)
    assert ur_main(["--host", HOST, "--fake", "--yes"]) == 2
    out, err = capsys.readouterr()
    assert served == [] and out == ""
    assert err.startswith("langctrl robot: error: live audio needs the PortAudio library")


def test_a_host_that_hangs_up_is_said_in_words() -> None:
    """ur-rtde's own "read: End of file" (the host took the connection, then closed it) becomes
    what happened and what to check."""
    import types

    from langenv.errors import DeviceError
    from langenv.robot.ur.bridge import URRobot
    from langenv.robot.ur.config import URConfig

    def hangs_up(*args: object, **kwargs: object) -> None:
        raise RuntimeError("read: End of file")

    backend = types.SimpleNamespace(
        probe=lambda host, timeout: None,
        RTDEReceiveInterface=hangs_up,
        RTDEControlInterface=hangs_up,
        DashboardClient=hangs_up,
    )
    with pytest.raises(DeviceError) as info:
        URRobot(URConfig(host=HOST), backend=backend)
    message = str(info.value)
    assert message.startswith(f"the robot at {HOST} does not answer as a UR's RTDE interface")
    assert "took the connection and closed it" in message and "Remote Control" in message


def test_import_needs_neither_ur_rtde_nor_mujoco_and_names_the_extra() -> None:
    code = (
        "import sys\n"
        "for m in ('rtde_control', 'rtde_receive', 'dashboard_client'): sys.modules[m] = None\n"
        "import langenv.robot.ur as ur\n"
        "assert 'mujoco' not in sys.modules, 'mujoco imported'\n"
        "from langenv.errors import DeviceError\n"
        "try:\n"
        "    ur.URRobot(ur.URConfig(host='127.0.0.1'))\n"
        "except DeviceError as e:\n"
        "    print(e)\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert ".[ur]" in out.stdout and "ur-rtde" in out.stdout


def test_fake_serves_loopback_only() -> None:
    with pytest.raises(ValueError, match="loopback"):
        fake_rtde.FakeUR("192.168.1.10")


def test_config_file_is_checked(tmp_path: Path) -> None:
    good = tmp_path / "ur.yaml"
    good.write_text("host: 127.0.0.1\ntcp_offset: [0, 0, 0.1, 0, 0, 90]\n")
    cfg = load_ur_config(good)
    assert cfg.tcp_offset[5] == pytest.approx(np.pi / 2)
    bad = tmp_path / "bad.yaml"
    bad.write_text("host: 127.0.0.1\npayload: 3\n")
    with pytest.raises(ConfigError, match="unknown key"):
        load_ur_config(bad)
    with pytest.raises(ConfigError, match="frequency"):
        URConfig(host=HOST, frequency=125.0)


def test_move_to_start_is_watched_and_interruptible() -> None:
    cfg = URConfig(host=HOST)
    with fake_rtde.FakeUR(HOST) as ur:
        robot = URRobot(cfg, backend=fake_rtde)
        calls = {"n": 0}
        real_read = robot.read

        def read():  # Ctrl-C half-way through the approach
            calls["n"] += 1
            if calls["n"] == 300:
                raise KeyboardInterrupt
            return real_read()

        robot.read = read  # type: ignore[method-assign]
        with pytest.raises(KeyboardInterrupt):
            move_to_start(robot, cfg, lambda q: True)
        robot.close()
    kinds = [c[0] for c in ur.commands if c[0] in ("moveL", "stopL", "speedStop")]
    assert kinds == ["moveL", "stopL", "speedStop"]
    assert not ur.velocity.any()


def test_an_error_inside_the_loop_still_stops_and_logs(tmp_path: Path) -> None:
    cfg = URConfig(host=HOST)
    policy = load_registered_policy("lc")
    act, calls = policy.act, {"n": 0}

    def failing_act(obs):
        calls["n"] += 1
        if calls["n"] == 1000:
            raise ValueError("a bug in the policy")
        return act(obs)

    policy.act = failing_act
    with fake_rtde.FakeUR(HOST) as ur:
        robot = URRobot(cfg, backend=fake_rtde)
        move_to_start(robot, cfg, lambda q: True)
        loop = RobotLoop(robot, policy, log_path=tmp_path / "session.csv")
        with pytest.raises(ValueError, match="bug in the policy"):
            loop.run()
    kinds = [c[0] for c in ur.commands if c[0] in ("speedL", "speedStop")]
    assert kinds[-1] == "speedStop"
    assert load_session(tmp_path / "session.csv").duration > 1.5


def test_zeroing_refuses_a_touched_handle() -> None:
    cfg = URConfig(host=HOST)
    with fake_rtde.FakeUR(HOST, person=lambda t, v: np.array([0.0, 0.0, 40.0 * t])) as ur:
        robot = URRobot(cfg, backend=fake_rtde)
        with pytest.raises(DeviceError, match="touching the handle"):
            zero_sensor(robot)
        robot.close()
    assert not [c for c in ur.commands if c[0] in ("moveL", "speedL")]


def test_the_shipped_set_up_file_loads() -> None:
    cfg = load_ur_config(Path(__file__).parents[1] / "configs" / "ur.yaml", host=HOST)
    assert cfg.host == HOST and cfg.period == pytest.approx(0.002)


def test_an_unsafe_exercise_is_refused_before_the_robot_is_contacted(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    served: list[fake_rtde.FakeUR] = []
    real_serve = fake_rtde.FakeUR.serve
    monkeypatch.setattr(
        fake_rtde.FakeUR, "serve", lambda self: served.append(self) or real_serve(self)
    )
    bad = tmp_path / "far.yaml"
    bad.write_text(
        "name: far\ntitle: Far\nstart: [-0.35, -0.55, 0.06]\nswitch_tol: 0.035\nlegs:\n"
        "  - name: reach\n    line: {to: [-0.35, -1.3, 0.06]}\n"
    )
    assert ur_main(["--host", HOST, "--fake", "--dry-run", "--exercise", str(bad)]) == 2
    err = capsys.readouterr().err
    assert "leg 'reach'" in err and "unreachable" in err
    assert not served  # refused before any connection
    assert ur_main(["--host", HOST, "--fake", "--dry-run", "--exercise", "no_such_one"]) == 2
    assert "no_such_one" in capsys.readouterr().err and not served


def test_the_bridge_goes_to_the_chosen_exercise_and_speaks_its_script(
    capsys: pytest.CaptureFixture[str],
) -> None:
    from langenv.exercise import resolve_exercise

    ex = resolve_exercise("hand_to_mouth")
    assert ur_main(["--host", HOST, "--fake", "--dry-run", "--exercise", "hand_to_mouth"]) == 0
    text = capsys.readouterr().out
    assert "'hand_to_mouth'" in text and str(np.round(ex.start, 4).tolist()) in text
    cfg = URConfig(host=HOST, exercise_origin=(0.01, 0.0, 0.0))
    with fake_rtde.FakeUR(HOST) as ur:
        robot = URRobot(cfg, backend=fake_rtde)
        move_to_start(robot, cfg, lambda q: True, ex)
        loop = RobotLoop(
            robot,
            load_registered_policy("lc"),
            trajectory=exercise_trajectory(cfg, ex),
            exercise=ex,
        )
        robot.close()
    np.testing.assert_allclose(ur.pose[:3], ex.start + np.array([0.01, 0.0, 0.0]), atol=1e-9)
    assert str(loop.env.graph.path).endswith("hand_to_mouth_lc.yaml")
    assert loop.env.motion.params.propel_force == ex.admittance().propel_force
    np.testing.assert_allclose(loop.env.motion.trajectory.position(0.0), ur.pose[:3], atol=1e-12)


def test_the_watchdog_is_fed_from_the_move_to_the_session_in_real_time() -> None:
    """On a wall clock, as on the robot: the slow move to the start kicks the 50 Hz watchdog,
    and the gap between that move's stop and the session's first command (env reset, policy
    reset...) does not trip it."""
    cfg = URConfig(host=HOST)
    start = exercise_trajectory(cfg).position(0.0)
    pose = (start[0], start[1], start[2] + 0.01, 0.0, 3.1416, 0.0)
    with fake_rtde.FakeUR(HOST, pose=pose, realtime=True) as ur:
        robot = URRobot(cfg, backend=fake_rtde)
        move_to_start(robot, cfg, lambda q: True)
        time.sleep(0.1)  # five watchdog periods at 50 Hz
        robot.enable()
        sent = robot.write_speed(np.array([0.01, 0, 0, 0, 0, 0.0]), 1.0, robot.period)
        assert sent[0] == pytest.approx(0.01) and ur.program_running
        robot.stop()
        robot.close()
    assert "watchdog" not in {c[0] for c in ur.commands}


def test_the_env_on_a_robot_sends_speed_stop_for_its_own_monitor_stop() -> None:
    """LangCtrl-v0 with robot= driven directly (no RobotLoop around it): a monitor stop (here the
    force limit) sends speedStop in the period that found it, not a last speedL left running."""
    from langenv.env import LangCtrlEnv

    cfg = URConfig(host=HOST)
    with fake_rtde.FakeUR(HOST) as ur:
        robot = URRobot(cfg, backend=fake_rtde)
        move_to_start(robot, cfg, lambda q: True)
        ur.inject("force_spike", 600, force=(0.0, 0.0, 300.0))
        env = LangCtrlEnv(robot=robot, trajectory=exercise_trajectory(cfg), decision_hz=50)
        env.reset(seed=0)
        for _ in range(200):
            _, _, terminated, _, info = env.step(np.zeros(env.action_space.shape, np.float32))
            if terminated:
                break
        assert info["safety_stop"] == "force"
        cmds = [c[0] for c in _speed_commands(ur)]
        assert cmds[-1] == "speedStop", cmds[-4:]
        assert cmds[-3:] == ["speedL", "waitPeriod", "speedStop"]
        robot.close()


def test_write_speed_keeps_speed_and_acceleration_within_the_set_up() -> None:
    """Whatever a caller of the seam asks, speedL goes out within max_speed and the set-up's
    speed_acceleration (ur-rtde itself accepts up to 150 m/s^2 and raises on a NaN)."""
    cfg = URConfig(host=HOST, speed_acceleration=0.5)
    with fake_rtde.FakeUR(HOST) as ur:
        c = fake_rtde.RTDEControlInterface(HOST)
        with pytest.raises(ValueError, match="NaN"):  # as ur-rtde's verifyValueIsWithin
            c.speedL([0.0] * 6, float("nan"))
        robot = URRobot(cfg, backend=fake_rtde, max_speed=0.2)
        robot.enable()
        for a in (100.0, float("nan"), -1.0, float("inf"), 0.3):
            sent = robot.write_speed(np.array([3.0, 0, 0, 0, 0, 0.0]), a, robot.period)
            assert np.linalg.norm(sent[:3]) == pytest.approx(0.2)
            assert ur._accel == (0.3 if a == 0.3 else 0.5), a
        robot.stop()
        robot.close()
    for bad in (float("nan"), 0.0, -0.5, float("inf")):
        with pytest.raises(ConfigError, match="max_speed"), fake_rtde.FakeUR(HOST):
            URRobot(cfg, backend=fake_rtde, max_speed=bad)


def test_ctrl_c_as_the_move_command_returns_still_ends_the_move() -> None:
    """A SIGINT during ur-rtde's blocking moveL call is raised as the call returns: the
    asynchronous move has started, and must be ended with stopL."""
    cfg = URConfig(host=HOST)
    with fake_rtde.FakeUR(HOST) as ur:
        robot = URRobot(cfg, backend=fake_rtde)
        real_move = robot._c.moveL

        def move_then_ctrl_c(*args):
            real_move(*args)
            raise KeyboardInterrupt

        robot._c.moveL = move_then_ctrl_c
        with pytest.raises(KeyboardInterrupt):
            move_to_start(robot, cfg, lambda q: True)
        for _ in range(10):
            robot.wait()
        robot.close()
    kinds = [c[0] for c in ur.commands if c[0] in ("moveL", "stopL", "speedStop")]
    assert kinds == ["moveL", "stopL", "speedStop"]
    assert not ur.velocity.any() and ur._move is None


class _BrokenSink:
    """A sound card that fails when the session ends (the device unplugged)."""

    def __init__(self, ring, sr: int) -> None:
        self.ring, self.xruns, self.alive = ring, 0, True

    def start(self) -> None:
        pass

    def stop(self) -> None:
        raise RuntimeError("PortAudio: device unavailable")


def test_a_failing_sound_card_at_the_end_still_stops_logs_and_restores_gc(tmp_path: Path) -> None:
    import gc

    cfg = URConfig(host=HOST)
    with fake_rtde.FakeUR(HOST) as ur:
        robot = URRobot(cfg, backend=fake_rtde)
        move_to_start(robot, cfg, lambda q: True)
        ur.inject("protective_stop", 300)
        loop = RobotLoop(
            robot,
            load_registered_policy("lc"),
            make_sink=_BrokenSink,
            log_path=tmp_path / "session.csv",
        )
        with pytest.raises(RuntimeError, match="device unavailable"):
            loop.run()
        robot.close()
    enabled = gc.isenabled()
    gc.unfreeze()
    gc.enable()  # for the tests after this one, whatever happened
    assert enabled
    assert [c[0] for c in _speed_commands(ur) if c[0] != "waitPeriod"][-1] == "speedStop"
    assert load_session(tmp_path / "session.csv").duration > 0.4


def test_a_dead_audio_sink_is_the_audio_lost_stop(tmp_path: Path) -> None:
    """The speech's writer thread dies mid-session (a failed write): the session stops with
    speedStop and its named stop instead of guiding the person on in silence."""
    from langenv.live.sinks import WavSink

    sinks: list[WavSink] = []

    def make_sink(ring, sr: int) -> WavSink:
        sink = WavSink(ring, tmp_path / "speech.wav", sr)
        write, calls = sink._file.write, {"n": 0}

        def failing_write(buf):
            calls["n"] += 1
            if calls["n"] == 1:
                raise OSError("No space left on device")
            return write(buf)

        sink._file.write = failing_write
        sinks.append(sink)
        return sink

    cfg = URConfig(host=HOST)
    with fake_rtde.FakeUR(HOST) as ur:
        robot = URRobot(cfg, backend=fake_rtde)
        move_to_start(robot, cfg, lambda q: True)
        loop = RobotLoop(
            robot, load_registered_policy("lc"), make_sink=make_sink, log_path=tmp_path / "s.csv"
        )
        assert sinks[0].alive  # not started yet
        report = loop.run()
        robot.close()
    assert report.stop is not None and report.stop.limit == "audio_lost", report.summary()
    _assert_stopped_in_time(ur)
    assert report.log is not None


def test_a_non_finite_command_is_a_stop_not_rest() -> None:
    """A NaN from the controller (a bug) stops the session with speedStop; it was sent as a
    zero speedL and the session went on."""
    from langenv.robot.io_arm import IOArm

    cfg = URConfig(host=HOST)
    with fake_rtde.FakeUR(HOST) as ur:
        robot = URRobot(cfg, backend=fake_rtde)
        arm = IOArm(robot)
        arm.reset()
        arm.step(np.array([0.01, 0.0, 0.0]), np.zeros(3))
        arm.step(np.array([np.nan, 0.0, 0.0]), np.zeros(3))
        arm.step(np.array([0.01, 0.0, 0.0]), np.zeros(3))
        robot.close()
    assert arm.fault is not None and arm.fault.limit == "bad_command"
    assert [c[0] for c in ur.commands if c[0] in ("speedL", "speedStop")] == ["speedL", "speedStop"]


def test_a_stop_stays_latched_until_the_operator_releases_it() -> None:
    """After a stop, env.reset() (or an autoreset wrapper) must not start the arm again by
    itself, even with the TCP still at the start: the operator confirms (IOArm.release())."""
    from langenv.robot.io_arm import IOArm

    cfg = URConfig(host=HOST)
    with fake_rtde.FakeUR(HOST) as ur:
        robot = URRobot(cfg, backend=fake_rtde)
        arm = IOArm(robot)
        arm.reset()
        arm.step(np.array([np.nan, 0.0, 0.0]), np.zeros(3))
        assert arm.fault is not None
        with pytest.raises(DeviceError, match="operator"):
            arm.reset()
        arm.step(np.array([0.01, 0.0, 0.0]), np.zeros(3))
        assert ur.speedl_count == 0
        arm.release()
        arm.reset()
        arm.step(np.array([0.01, 0.0, 0.0]), np.zeros(3))
        assert ur.speedl_count == 1
        robot.close()


def test_a_second_ctrl_c_during_the_stop_still_logs(tmp_path: Path) -> None:
    """Ctrl-C pressed twice: the second arrives as speedStop returns (Python raises it after the
    blocking call). The stop went out; the log and the garbage collector must survive it."""
    import gc

    cfg = URConfig(host=HOST)
    with fake_rtde.FakeUR(HOST) as ur:
        robot = URRobot(cfg, backend=fake_rtde)
        move_to_start(robot, cfg, lambda q: True)
        ur.inject("protective_stop", 300)
        real_stop, calls = robot.stop, {"n": 0}

        def stop_then_ctrl_c() -> None:
            real_stop()
            calls["n"] += 1
            if calls["n"] == 2:  # the first is the fault's own
                raise KeyboardInterrupt

        robot.stop = stop_then_ctrl_c  # type: ignore[method-assign]
        loop = RobotLoop(robot, load_registered_policy("lc"), log_path=tmp_path / "s.csv")
        with pytest.raises(KeyboardInterrupt):
            loop.run()
        robot.close()
    enabled = gc.isenabled()
    gc.unfreeze()
    gc.enable()
    assert enabled
    assert load_session(tmp_path / "s.csv").duration > 0.4
    assert [c[0] for c in _speed_commands(ur) if c[0] != "waitPeriod"][-1] == "speedStop"


def test_write_speed_sends_no_unbounded_rotation() -> None:
    """No limit bounds an angular velocity: the bridge sends none (MujocoRobot ignores it too)."""
    cfg = URConfig(host=HOST)
    with fake_rtde.FakeUR(HOST) as ur:
        robot = URRobot(cfg, backend=fake_rtde)
        robot.enable()
        sent = robot.write_speed(np.array([0.01, 0, 0, 6.0, -6.0, 6.0]), 1.0, robot.period)
        robot.stop()
        robot.close()
    last = [c for c in ur.commands if c[0] == "speedL"][-1][2]
    assert last[3:] == [0.0, 0.0, 0.0] and not sent[3:].any() and last[0] == pytest.approx(0.01)


def test_robot_refuses_to_replace_a_log_without_overwrite(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from langctrl.jobs.robot import parse_args

    log = tmp_path / "session.csv"
    log.write_text("t\n0\n")
    with pytest.raises(SystemExit):
        parse_args(["--host", HOST, "--fake", "--log-out", str(log)])
    assert f"--log-out {log}: exists; give --overwrite" in capsys.readouterr().err
    assert parse_args(["--host", HOST, "--fake", "--log-out", str(log), "--overwrite"]).overwrite
