"""URRobot: a real UR (or URSim) behind the robot-IO seam, through ``ur-rtde``.

``ur-rtde`` is an optional extra (``pip install -e ".[ur]"``), imported here only, when a
:class:`URRobot` is made (:func:`ur_rtde_backend`); without it the error names the extra. Tests
pass ``backend=langenv.robot.ur.fake_rtde`` instead: the same classes and signatures, a
simulated robot on a loopback host.

Per period the loop calls :meth:`URRobot.write_speed` (``speedL`` and a watchdog kick),
:meth:`URRobot.wait` (``waitPeriod`` then ``initPeriod``: the lateness is measured on the
library's own steady clock) and :meth:`URRobot.read` (seven cached RTDE values). Any
``RuntimeError`` from the library, a ``False`` from a command, an interface no longer
connected, or an RTDE timestamp that stops advancing is a lost link
(:class:`~langenv.errors.DeviceError`, the ``connection_lost`` stop).
"""

from __future__ import annotations

import socket
import types
from typing import Any

import numpy as np
from numpy.typing import NDArray

from langenv.errors import ConfigError, DeviceError
from langenv.robot.io import RobotContext, RobotState, limit_speed
from langenv.robot.safety import DEFAULT_MAX_SPEED
from langenv.robot.ur.config import URConfig
from langenv.validation import finite_positive

__all__ = [
    "IDLE_WATCHDOG_HZ",
    "INSTALL_HINT",
    "RTDE_PORT",
    "STALE_PERIODS",
    "URRobot",
    "ur_rtde_backend",
]

RTDE_PORT = 30004
"""The robot's RTDE port."""

STALE_PERIODS = 10
"""An RTDE timestamp unchanged for this many periods in a row is a lost link."""

IDLE_WATCHDOG_HZ = 0.2
"""The RTDE watchdog's rate (Hz) once a ``speedStop`` went through: the arm is at rest and
commanded nothing, so the watchdog (which stops ur-rtde's control script when no command arrives
for 1/rate s) only has to outlast the gap to the next :meth:`URRobot.enable` (the move to the
start, then the session, both re-arm it at ``watchdog_hz``)."""

INSTALL_HINT = 'pip install -e ".[ur]"  (or: pip install "ur-rtde>=1.6")'

UR5_JOINTS = ("base", "shoulder", "elbow", "wrist_1", "wrist_2", "wrist_3")


def ur_rtde_backend() -> Any:
    """``ur-rtde``'s three modules as one namespace (imported here, late, in one place).

    Raises:
        DeviceError: ``ur-rtde`` is not installed (naming the extra to install).
    """
    try:
        import dashboard_client
        import rtde_control
        import rtde_receive
    except ImportError as exc:
        raise DeviceError(
            f"the UR bridge needs ur-rtde, which is not installed: {INSTALL_HINT}"
        ) from exc
    return types.SimpleNamespace(
        RTDEControlInterface=rtde_control.RTDEControlInterface,
        RTDEReceiveInterface=rtde_receive.RTDEReceiveInterface,
        DashboardClient=dashboard_client.DashboardClient,
        probe=_probe,
    )


def _no_rtde_answer(host: str, exc: RuntimeError) -> DeviceError:
    """The error of a host that takes the connection but does not speak RTDE to us (ur-rtde
    says ``read: End of file`` when it hangs up), in words and with what to check."""
    why = str(exc).strip() or type(exc).__name__
    hung_up = "end of file" in why.lower() or "reset by peer" in why.lower()
    what = "took the connection and closed it" if hung_up else "did not answer as a UR"
    return DeviceError(
        f"the robot at {host} does not answer as a UR's RTDE interface: it {what} "
        f"(ur-rtde: {why}); check that {host} is the robot (or URSim), that its controller is "
        "started and the robot is in Remote Control, and that no other program holds its "
        "RTDE connection"
    )


def _probe(host: str, timeout: float) -> None:
    """Open and close a TCP connection to the RTDE port (so a silent host fails in ``timeout``)."""
    with socket.create_connection((host, RTDE_PORT), timeout=timeout):
        pass


class URRobot(RobotContext):
    """A UR through ``ur-rtde``, as a :class:`~langenv.robot.io.RobotIO`.

    Connecting checks that the host answers within ``config.connect_timeout``, then opens the
    receive, control and dashboard interfaces. The robot starts stopped: :meth:`enable` before
    commanding (the session does, after the preflight).

    Args:
        config: The set-up.
        backend: The library's namespace (default: :func:`ur_rtde_backend`).
        max_speed: The robot-side TCP speed clip of :meth:`write_speed` (m/s), > 0.

    Raises:
        ConfigError: ``max_speed`` not a finite number > 0.
        DeviceError: ``ur-rtde`` missing, or no robot answers at ``config.host`` (the host named).
    """

    def __init__(
        self, config: URConfig, *, backend: Any = None, max_speed: float = DEFAULT_MAX_SPEED
    ) -> None:
        self.config = config
        self.max_speed = finite_positive("URRobot.max_speed", max_speed, ConfigError)
        lib = backend if backend is not None else ur_rtde_backend()
        host = config.host
        try:
            lib.probe(host, config.connect_timeout)
        except OSError as exc:
            raise DeviceError(
                f"no robot answers at {host}:{RTDE_PORT} within {config.connect_timeout:g} s "
                f"({exc}): check the address, the cable and that the robot (or URSim) is on"
            ) from None
        try:
            prio = config.rt_priority
            self._r = lib.RTDEReceiveInterface(host, config.frequency, rt_priority=prio)
            self._c = lib.RTDEControlInterface(host, config.frequency, rt_priority=prio)
            self._d = lib.DashboardClient(host)
            self._d.connect(round(1000 * config.connect_timeout))
        except RuntimeError as exc:
            raise _no_rtde_answer(host, exc) from None
        self._enabled = self._ever_enabled = False
        self._period = config.period
        self._t = self._call(self._c.initPeriod)
        self._stamp = -1.0
        self._same_stamp = 0
        self.stops_sent = 0

    # ------------------------------------------------------------------ RobotIO
    @property
    def period(self) -> float:
        """Control period (s)."""
        return self._period

    @property
    def joint_names(self) -> tuple[str, ...]:
        """A UR's six joints."""
        return UR5_JOINTS

    @property
    def joint_limits(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """The configured joint ranges (rad)."""
        return self.config.joint_lower.copy(), self.config.joint_upper.copy()

    def _call(self, fn: Any, *args: Any) -> Any:
        try:
            return fn(*args)
        except RuntimeError as exc:
            raise DeviceError(f"link to the robot at {self.config.host} lost: {exc}") from None

    def read(self) -> RobotState:
        """The robot's state (RTDE receive), checked fresh: both interfaces connected (ur-rtde's
        getters return their last values without raising once a link is lost) and the RTDE
        timestamp advancing."""
        r = self._r
        try:
            linked = r.isConnected() and self._c.isConnected()
            stamp = r.getTimestamp()
            state = RobotState(
                stamp,
                r.getActualTCPPose(),
                r.getActualTCPSpeed(),
                r.getActualQ(),
                r.getActualTCPForce(),
                r.isProtectiveStopped(),
                r.isEmergencyStopped(),
                self._c.isProgramRunning(),
            )
        except RuntimeError as exc:
            raise DeviceError(f"link to the robot at {self.config.host} lost: {exc}") from None
        if not linked:
            raise DeviceError(f"the link to the robot at {self.config.host} is lost (ur-rtde)")
        self._same_stamp = self._same_stamp + 1 if stamp == self._stamp else 0
        self._stamp = stamp
        if self._same_stamp >= STALE_PERIODS:
            raise DeviceError(
                f"the robot at {self.config.host} sent no new state for {STALE_PERIODS} periods"
            )
        return state

    def write_speed(
        self, xd: NDArray[np.float64], acceleration: float, time: float
    ) -> NDArray[np.float64]:
        """``speedL`` of ``xd``'s linear part clipped to ``max_speed`` (its angular part is not
        sent: no limit bounds it, and the session holds the orientation), at an
        ``acceleration`` clipped to the set-up's ``speed_acceleration`` (a NaN or one <= 0
        becomes that limit too), and a watchdog kick; zeros, and nothing sent, once stopped."""
        if not self._enabled:
            return np.zeros(6)
        sent = limit_speed(xd, self.max_speed)
        sent[3:] = 0.0  # no rotation: the session holds the TCP's orientation (as MujocoRobot)
        a_max = self.config.speed_acceleration
        a = acceleration if 0.0 < acceleration <= a_max else a_max
        c = self._c
        try:
            ok = c.speedL(sent.tolist(), a, time)
            c.kickWatchdog()
            if not ok:  # explained by a stop the next read reports, or the link is gone
                r = self._r
                explained = (
                    r.isProtectiveStopped() or r.isEmergencyStopped() or not c.isProgramRunning()
                )
        except RuntimeError as exc:
            raise DeviceError(f"link to the robot at {self.config.host} lost: {exc}") from None
        if not ok:
            if not explained:
                raise DeviceError(f"the robot at {self.config.host} refused speedL")
            return np.zeros(6)
        return sent

    def wait(self) -> float:
        """``waitPeriod`` for the current period, then start the next; returns its lateness."""
        c = self._c
        try:
            c.waitPeriod(self._t)
            t = c.initPeriod()
        except RuntimeError as exc:
            raise DeviceError(f"link to the robot at {self.config.host} lost: {exc}") from None
        late = (t - self._t).total_seconds() - self._period
        self._t = t
        return late if late > 0.0 else 0.0

    def zero_ft_sensor(self) -> None:
        """``zeroFtSensor`` (the caller checks the arm is at rest)."""
        if not self._call(self._c.zeroFtSensor):
            raise DeviceError(f"the robot at {self.config.host} refused zeroFtSensor")

    def stop(self) -> None:
        """``speedStop`` at ``config.stop_deceleration``; latched until :meth:`enable`. Once the
        arm is stopped the watchdog is slowed to :data:`IDLE_WATCHDOG_HZ`. A robot never
        enabled has been commanded nothing, and is sent nothing (a dry run)."""
        self._enabled = False
        if not self._ever_enabled:
            return
        self.stops_sent += 1
        if self._call(self._c.speedStop, self.config.stop_deceleration):
            self._call(self._c.setWatchdog, IDLE_WATCHDOG_HZ)

    def enable(self) -> None:
        """Accept commands (arms the RTDE watchdog at ``watchdog_hz``) and restart the period
        clock.

        Raises:
            DeviceError: the robot's control script does not run (a stop, the watchdog, or the
                pendant ended it): nothing is commanded.
        """
        if not self._call(self._c.setWatchdog, self.config.watchdog_hz):
            raise DeviceError(
                f"the robot at {self.config.host} does not take commands: ur-rtde's control "
                "script is not running (a protective or emergency stop, its watchdog, or the "
                "pendant stopped it)"
            )
        self._t = self._call(self._c.initPeriod)
        self._enabled = self._ever_enabled = True

    def close(self) -> None:
        """Stop the control script and disconnect (best effort: the link may be gone)."""
        for fn in (self._c.stopScript, self._c.disconnect, self._r.disconnect, self._d.disconnect):
            try:
                fn()
            except RuntimeError:
                pass

    # ------------------------------------------------------------------ preflight's needs
    def controller_version(self) -> str:
        """PolyScope's version string (dashboard)."""
        return str(self._call(self._d.polyscopeVersion))

    def payload(self) -> tuple[float, NDArray[np.float64]]:
        """Payload mass (kg) and centre of gravity (3,) m as set on the robot."""
        mass = float(self._call(self._r.getPayload))
        return mass, np.array(self._call(self._r.getPayloadCog), dtype=np.float64)

    def tcp_offset(self) -> NDArray[np.float64]:
        """The TCP offset set on the robot, (6,) m and rotation vector rad."""
        return np.array(self._call(self._c.getTCPOffset), dtype=np.float64)

    def is_steady(self) -> bool:
        """Whether the robot reports itself fully at rest."""
        return bool(self._call(self._c.isSteady))

    def pose_within_limits(self, pose: NDArray[np.float64]) -> bool:
        """Whether ``pose`` (6,) is within the robot's own safety limits."""
        return bool(self._call(self._c.isPoseWithinSafetyLimits, pose.tolist()))

    def move_linear(self, pose: NDArray[np.float64], speed: float, acceleration: float) -> None:
        """``moveL`` to ``pose`` (6,), asynchronous and watched every period (which also kicks the
        RTDE watchdog): Ctrl-C, a stop of the robot's, or a move that takes twice as long as it
        should (plus 2 s) ends it with ``stopL`` at ``stop_deceleration`` (only while enabled).

        Raises:
            DeviceError: refused, stopped by the robot, or too slow; KeyboardInterrupt passes on
                after ``stopL``.
        """
        if not self._enabled:
            raise DeviceError("move_linear: the robot is stopped (enable it first)")
        c = self._c
        start = self.read().position
        budget = 2.0 * float(np.linalg.norm(pose[:3] - start)) / speed + 2.0
        waited = 0.0
        try:  # from the moveL on: a Ctrl-C delivered as the call returns also ends in stopL
            if not self._call(c.moveL, pose.tolist(), speed, acceleration, True):
                raise DeviceError(
                    f"the robot at {self.config.host} refused moveL to {pose.tolist()}"
                )
            while self._call(c.getAsyncOperationProgress) >= 0:
                self._call(c.kickWatchdog)
                self.wait()
                waited += self._period
                state = self.read()
                if state.protective_stop or state.emergency_stop or not state.program_running:
                    raise DeviceError("the robot stopped during the move to the exercise's start")
                if waited > budget:
                    raise DeviceError(f"the move to the exercise's start took over {budget:.1f} s")
        except BaseException:
            self._call(c.stopL, self.config.stop_deceleration, False)
            raise
