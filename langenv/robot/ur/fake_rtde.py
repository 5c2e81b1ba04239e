"""A fake of ``ur-rtde``'s ``rtde_control`` / ``rtde_receive`` / ``dashboard_client`` for tests.

The classes below have the names, argument order, defaults and positional-only rules of ur-rtde
1.6 (its pybind signatures: an argument the library leaves unnamed, ``arg0``, is positional-only
here too; ``tests/test_ur_fake_rtde.py`` compares them with the installed library). They talk to a
:class:`FakeUR` registered on a loopback host name instead of a robot, so the real bridge
(:class:`~langenv.robot.ur.bridge.URRobot`) runs its own code against them
(``URRobot(config, backend=fake_rtde)``).

:class:`FakeUR` integrates the commanded TCP velocity (``speedL``: the velocity ramps to the
command at the given acceleration; ``speedStop``: to rest at its deceleration) on a **virtual
clock** that ``waitPeriod`` advances by one period (so a 10 s session takes the CPU time of its
loop, not 10 s), and injects faults (:meth:`FakeUR.inject`) at a given ``speedL`` command index:

| fault | effect |
|---|---|
| ``late`` | that ``waitPeriod`` returns ``extra`` s late |
| ``protective_stop`` | ``isProtectiveStopped()`` is True, the arm halts, the script stops |
| ``emergency_stop`` | ``isEmergencyStopped()`` is True, likewise |
| ``program_stop`` | ``isProgramRunning()`` is False, commands are ignored |
| ``disconnect`` | commands raise ``RuntimeError`` (the reconnect fails); reads: see below |
| ``receive_lost`` | the receive thread died (on a socket error); commands still go out |
| ``force_spike`` | ``force`` N (3,) added to the wrist reading for ``duration`` s |
| ``stuck_sensor`` | the wrist reading freezes at its current value |
| ``joint_limit`` | joint ``joint`` moves to ``margin`` rad inside its range's upper end |
| ``stale_state`` | the RTDE timestamp (and the state) stop advancing: a receive thread gone quiet |

After ``disconnect`` or ``receive_lost``, as in ur-rtde, reading returns the last state received
without raising, and ``isConnected()`` is False (the receive interface's; after ``disconnect``
the control interface's too).

As on the robot, ``setWatchdog(f)`` arms ur-rtde's RTDE watchdog with the action "stop": when no
RTDE input (any command: ``speedL``, ``kickWatchdog``, ``speedStop``, ``moveL``...; reading the
state is no input) arrives for ``1/f`` s, the control script stops (the arm halts, commands are
refused, ``isProgramRunning()`` is False) and the watchdog is removed. Commands answer False
while the script does not run or the robot is stopped, as ur-rtde's ``sendCommand`` does.
"""

from __future__ import annotations

import datetime
import math
import time as _time
import types
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

__all__ = [
    "FAULTS",
    "DashboardClient",
    "FakeUR",
    "RTDEControlInterface",
    "RTDEReceiveInterface",
    "probe",
]

FAULTS = (
    "late",
    "protective_stop",
    "emergency_stop",
    "program_stop",
    "disconnect",
    "receive_lost",
    "force_spike",
    "stuck_sensor",
    "joint_limit",
    "stale_state",
)
"""The faults :meth:`FakeUR.inject` knows."""

_SERVERS: dict[str, FakeUR] = {}
_LOOPBACK = ("127.0.0.1", "localhost", "::1")


@dataclass
class _Fault:
    kind: str
    at: int
    params: dict[str, Any]


class FakeUR:
    """A simulated UR on a loopback host name, what the fake interfaces talk to.

    Args:
        host: A loopback address (tests never name another).
        period: The control period (s).
        pose: The TCP's initial pose (6,): m, rotation vector rad.
        person: The person's force on the handle ``f(t, tcp_velocity) -> (3,) N`` (default none).
        noise: Wrist sensor noise (N, std per axis), from a generator seeded with ``seed``.
        version: What ``polyscopeVersion()`` answers.
        payload: (mass kg, cog (3,) m) set on the robot; ``tcp_offset`` (6,) likewise.
        realtime: ``waitPeriod`` sleeps until the period's end on the wall clock (as the real
            library does) instead of advancing a virtual clock.

    Attributes:
        commands: Every command received, in order: ``("speedL", period, xd)``,
            ``("speedStop", period, a)``, ``("moveL", period, pose)``, ``("stopL", period, a)``,
            ``("waitPeriod", period)``,
            ``("stopScript", period)``.
        period_index: Periods elapsed on the virtual clock.
    """

    def __init__(
        self,
        host: str = "127.0.0.1",
        *,
        period: float = 0.002,
        pose: Sequence[float] = (-0.35, -0.58, 0.1, 0.0, 3.1416, 0.0),
        person: Callable[[float, NDArray[np.float64]], NDArray[np.float64]] | None = None,
        noise: float = 0.1,
        seed: int = 0,
        version: str = "URSoftware 5.11.1.108318 (Mar 22 2021)",
        payload: tuple[float, Sequence[float]] = (0.6, (0.0, 0.0, 0.05)),
        tcp_offset: Sequence[float] = (0.0, 0.0, 0.1, 0.0, 0.0, 0.0),
        realtime: bool = False,
    ) -> None:
        if host not in _LOOPBACK:
            raise ValueError(f"FakeUR serves a loopback address only, got {host!r}")
        self.host = host
        self.period = float(period)
        self.pose = np.array(pose, dtype=np.float64)
        self.velocity = np.zeros(6)
        self.q = np.array([0.0, -1.57, 1.57, -1.57, -1.57, 0.0])
        self.person = person
        self.noise = float(noise)
        self._rng = np.random.default_rng(seed)
        self.version = version
        self.payload_mass, self.payload_cog = float(payload[0]), list(payload[1])
        self.tcp_offset = list(tcp_offset)
        self.clock = 0.0
        self.realtime = bool(realtime)
        self._t0 = _time.perf_counter()
        self.period_index = 0
        self.commands: list[tuple[Any, ...]] = []
        self.faults: list[_Fault] = []
        self.speedl_count = 0
        self._target = np.zeros(6)
        self._accel = 0.0
        self.protective_stop = self.emergency_stop = False
        self.program_running = True
        self.connected = True
        self._ft_offset = np.zeros(3)
        self._stuck: list[float] | None = None
        self._spike = np.zeros(3)
        self._spike_until = -1.0
        self._late = 0.0
        self.timestamp = 0.0
        self._move: tuple[NDArray[np.float64], float] | None = None
        self.stale = False
        self._async_done = -1
        self.watchdog_hz = 0.0
        self._last_input = 0.0
        self.receive_connected = True
        self._snapshot: Any = None

    # ------------------------------------------------------------------ set-up
    def serve(self) -> FakeUR:
        """Register on its host name, so the fake interfaces find it; returns itself."""
        _SERVERS[self.host] = self
        return self

    def shutdown(self) -> None:
        """Unregister (interfaces made later cannot connect)."""
        if _SERVERS.get(self.host) is self:
            del _SERVERS[self.host]

    def __enter__(self) -> FakeUR:
        return self.serve()

    def __exit__(self, *exc: object) -> None:
        self.shutdown()

    def inject(self, kind: str, at: int, **params: Any) -> None:
        """Inject ``kind`` (one of :data:`FAULTS`) when the ``at``-th ``speedL`` arrives."""
        if kind not in FAULTS:
            raise ValueError(f"unknown fault {kind!r}; known: {', '.join(FAULTS)}")
        self.faults.append(_Fault(kind, int(at), params))

    # ------------------------------------------------------------------ what the robot does
    def check_link(self) -> None:
        if not self.connected:
            raise RuntimeError("RTDE connection lost (fake)")
        self._watch(self.now())

    def received(self) -> Any:
        """What the receive interface reads: this robot, or once its link is lost the last
        state received (ur-rtde's getters return their cache and never raise)."""
        if self._snapshot is not None:
            return self._snapshot
        self._watch(self.now())
        return self

    def _lose_receive(self) -> None:
        wrench = self.wrench()
        self._snapshot = types.SimpleNamespace(
            pose=self.pose.copy(),
            velocity=self.velocity.copy(),
            q=self.q.copy(),
            protective_stop=self.protective_stop,
            emergency_stop=self.emergency_stop,
            program_running=self.program_running,
            timestamp=self.timestamp,
            payload_mass=self.payload_mass,
            payload_cog=list(self.payload_cog),
            wrench=lambda: list(wrench),
        )
        self.receive_connected = False

    def command(self) -> bool:
        """An RTDE input (a command) arrives: feeds the watchdog; whether the script takes it."""
        self.check_link()
        self._last_input = self.now()
        return self.moving_allowed

    def set_watchdog(self, hz: float) -> bool:
        ok = self.command()
        if ok:
            self.watchdog_hz = float(hz)
        return ok

    def _watch(self, t: float) -> None:
        """The RTDE watchdog: no input for 1/watchdog_hz s stops the control script."""
        hz = self.watchdog_hz
        if hz > 0.0 and self.program_running and t - self._last_input > 1.0 / hz + 1e-9:
            self.commands.append(("watchdog", self.period_index))
            self.stop_script()

    def stop_script(self) -> None:
        """The control script stops: the arm halts, and the watchdogs are removed."""
        self.program_running = False
        self.watchdog_hz = 0.0
        self._move = None
        self._halt()

    @property
    def moving_allowed(self) -> bool:
        return self.program_running and not (self.protective_stop or self.emergency_stop)

    def speed_command(self, xd: Sequence[float], acceleration: float) -> bool:
        self.check_link()
        self._last_input = self.now()
        self.speedl_count += 1
        for fault in [f for f in self.faults if f.at == self.speedl_count - 1]:
            self._apply(fault)
            self.faults.remove(fault)
        self.check_link()
        self.commands.append(("speedL", self.period_index, list(xd)))
        if not self.moving_allowed:
            return False
        self._target = np.array(xd, dtype=np.float64)
        self._accel = float(acceleration)
        return True

    def stop_command(self, a: float) -> bool:
        ok = self.command()
        self.commands.append(("speedStop", self.period_index, float(a)))
        self._target = np.zeros(6)
        self._accel = float(a)
        return ok

    def _apply(self, fault: _Fault) -> None:
        kind, p = fault.kind, fault.params
        if kind == "late":
            self._late += float(p.get("extra", 0.01))
        elif kind in ("protective_stop", "emergency_stop"):
            setattr(self, kind, True)
            self._halt()
        elif kind == "program_stop":
            self.stop_script()
        elif kind == "disconnect":
            self._lose_receive()
            self.connected = False
        elif kind == "receive_lost":
            self._lose_receive()
        elif kind == "force_spike":
            self._spike = np.array(p.get("force", (0.0, 0.0, 200.0)), dtype=np.float64)
            self._spike_until = self.clock + float(p.get("duration", 0.05))
        elif kind == "stuck_sensor":
            self._stuck = self.wrench()
        elif kind == "stale_state":
            self.stale = True
        elif kind == "joint_limit":
            j = int(p.get("joint", 0))
            self.q[j] = 2.0 * np.pi - float(p.get("margin", 0.005))

    def _halt(self) -> None:
        self._target = np.zeros(6)
        self.velocity = np.zeros(6)

    def advance(self) -> None:
        """One period: the velocity ramps towards the command, the pose integrates it (or an
        asynchronous ``moveL`` goes on at its speed)."""
        dt = self.period
        if not self.moving_allowed:
            self._target = np.zeros(6)
            self.velocity = np.zeros(6)
            self._move = None
        if self._move is not None:
            self._step_move(dt)
            return
        dv = self._target - self.velocity
        lin = float(np.linalg.norm(dv[:3]))
        step = self._accel * dt
        if lin > step > 0.0:
            dv[:3] *= step / lin
        elif step == 0.0:
            dv[:3] = 0.0
        self.velocity = self.velocity + dv
        self.pose[:3] += self.velocity[:3] * dt
        self.clock += dt
        if not self.stale:
            self.timestamp = self.clock
        self.period_index += 1
        self._watch(self.clock)

    def now(self) -> float:
        """The clock ``initPeriod`` reads (s): virtual, or the wall clock when ``realtime``."""
        return _time.perf_counter() - self._t0 if self.realtime else self.clock

    def wait(self, t_start: float) -> None:
        """Advance the clock to one period after ``t_start`` (plus injected lateness); the
        library's own steady clock: works without a link."""
        self.commands.append(("waitPeriod", self.period_index))
        due = t_start + self.period + self._late
        self._late = 0.0
        if self.realtime:
            while (left := due - self.now()) > 0.0:
                _time.sleep(left - 0.0007 if left > 0.0007 else 0.0)  # then spin
            due = self.now()
            idle = not (self.velocity.any() or self._target.any() or self._move is not None)
            if idle:  # at rest while nobody waited (set-up): skip the idle periods at once
                skipped = int(max(0.0, due - self.period - self.clock) / self.period)
                self.clock += skipped * self.period
                self.period_index += skipped
        while self.clock < due - 1e-12:
            self.advance()

    def _step_move(self, dt: float) -> None:
        assert self._move is not None
        target, speed = self._move
        gap = target[:3] - self.pose[:3]
        dist = float(np.linalg.norm(gap))
        if dist <= speed * dt:
            self.pose = target.copy()
            self.velocity = np.zeros(6)
            self._move = None
            self._async_done = -2 if self._async_done == -1 else -1
        else:
            self.velocity = np.zeros(6)
            self.velocity[:3] = gap / dist * speed
            self.pose[:3] += self.velocity[:3] * dt
        self.clock += dt
        self.timestamp = self.clock
        self.period_index += 1
        self._watch(self.clock)

    def async_progress(self) -> int:
        self.check_link()
        return 0 if self._move is not None else self._async_done

    def stop_move(self, a: float) -> None:
        self.command()
        self.commands.append(("stopL", self.period_index, float(a)))
        self._move = None
        self.velocity = np.zeros(6)

    def wrench(self) -> list[float]:
        if self._stuck is not None:
            return list(self._stuck)
        f = np.zeros(3)
        if self.person is not None:
            f = np.asarray(self.person(self.clock, self.velocity[:3].copy()), np.float64)
        if self.clock < self._spike_until:
            f = f + self._spike
        f = f - self._ft_offset + self._rng.normal(0.0, self.noise, 3)
        return [*f.tolist(), *self._rng.normal(0.0, 0.01 * self.noise, 3).tolist()]

    def zero_sensor(self) -> bool:
        if not self.command():
            return False
        self._ft_offset = self._ft_offset + np.array(self.wrench()[:3])
        return True

    def move_to(self, pose: Sequence[float], speed: float, asynchronous: bool = False) -> bool:
        if not self.command():
            return False
        self.commands.append(("moveL", self.period_index, list(pose)))
        target = np.array(pose, dtype=np.float64)
        if asynchronous:
            self._move = (target, float(speed))
            return True
        distance = float(np.linalg.norm(target[:3] - self.pose[:3]))
        periods = int(np.ceil(distance / (speed * self.period)))
        if self.realtime:
            _time.sleep(periods * self.period)
        for _ in range(periods):
            self.clock += self.period
            self.period_index += 1
        self.pose = target
        self.velocity = np.zeros(6)
        self.timestamp = self.clock
        return True


def _within(value: float, lo: float, hi: float) -> None:
    """ur-rtde's ``verifyValueIsWithin``: a NaN or a value outside [lo, hi] raises ValueError
    (its ``std::invalid_argument`` / ``std::range_error`` through pybind11)."""
    if math.isnan(value):
        raise ValueError("The value is considered NaN")
    if not lo <= value <= hi:
        raise ValueError(f"The value is not within [{lo:g};{hi:g}]")


def _server(hostname: str) -> FakeUR:
    server = _SERVERS.get(hostname)
    if server is None:
        raise RuntimeError(f"Error: Could not connect to: {hostname} at 30004, verify the IP")
    return server


def probe(host: str, timeout: float) -> None:
    """What the bridge's reachability check does on this fake: a registered host answers."""
    if host not in _SERVERS:
        raise OSError(f"[Errno 111] Connection refused ({host}:30004)")


class RTDEControlInterface:
    """Fake of ``rtde_control.RTDEControlInterface`` (the methods the bridge uses)."""

    def __init__(
        self,
        hostname: str,
        frequency: float = -1.0,
        flags: int = 1,
        ur_cap_port: int = 50002,
        rt_priority: int = 0,
    ) -> None:
        self._ur = _server(hostname)

    def speedL(self, xd: list[float], acceleration: float = 0.25, time: float = 0.0) -> bool:
        _within(acceleration, 0.0, 150.0)  # ur-rtde's UR_TOOL_ACCELERATION_MIN/MAX
        return self._ur.speed_command(xd, acceleration)

    def speedStop(self, a: float = 10.0) -> bool:
        return self._ur.stop_command(a)

    def initPeriod(self) -> datetime.timedelta:
        return datetime.timedelta(seconds=self._ur.now())

    def waitPeriod(self, arg0: datetime.timedelta, /) -> None:
        self._ur.wait(arg0.total_seconds())

    def zeroFtSensor(self) -> bool:
        return self._ur.zero_sensor()

    def moveL(
        self,
        pose: list[float],
        speed: float = 0.25,
        acceleration: float = 1.2,
        asynchronous: bool = False,
    ) -> bool:
        return self._ur.move_to(pose, speed, asynchronous)

    def getAsyncOperationProgress(self) -> int:
        return self._ur.async_progress()

    def stopL(self, a: float = 10.0, asynchronous: bool = False) -> None:
        self._ur.stop_move(a)

    def isSteady(self) -> bool:
        return bool(not self._ur.received().velocity.any())

    def isProgramRunning(self) -> bool:
        return bool(self._ur.received().program_running)

    def isPoseWithinSafetyLimits(self, arg0: list[float], /) -> bool:
        self._ur.check_link()
        return True

    def getTCPOffset(self) -> list[float]:
        self._ur.check_link()
        return list(self._ur.tcp_offset)

    def setWatchdog(self, min_frequency: float = 10.0) -> bool:
        return self._ur.set_watchdog(min_frequency)

    def kickWatchdog(self) -> bool:
        return self._ur.command()

    def stopScript(self) -> None:
        self._ur.command()
        self._ur.commands.append(("stopScript", self._ur.period_index))
        self._ur.stop_script()

    def isConnected(self) -> bool:
        return self._ur.connected

    def disconnect(self) -> None:
        return None


class RTDEReceiveInterface:
    """Fake of ``rtde_receive.RTDEReceiveInterface`` (the methods the bridge uses)."""

    def __init__(
        self,
        hostname: str,
        frequency: float = -1.0,
        variables: list[str] = [],  # noqa: B006 - the library's own default
        verbose: bool = False,
        use_upper_range_registers: bool = False,
        rt_priority: int = 0,
    ) -> None:
        self._ur = _server(hostname)

    def getActualTCPPose(self) -> list[float]:
        ur = self._ur.received()
        return ur.pose.tolist()

    def getActualTCPSpeed(self) -> list[float]:
        ur = self._ur.received()
        return ur.velocity.tolist()

    def getActualQ(self) -> list[float]:
        ur = self._ur.received()
        return ur.q.tolist()

    def getActualTCPForce(self) -> list[float]:
        ur = self._ur.received()
        return ur.wrench()

    def isProtectiveStopped(self) -> bool:
        ur = self._ur.received()
        return ur.protective_stop

    def isEmergencyStopped(self) -> bool:
        ur = self._ur.received()
        return ur.emergency_stop

    def getTimestamp(self) -> float:
        ur = self._ur.received()
        return ur.timestamp

    def getPayload(self) -> float:
        ur = self._ur.received()
        return ur.payload_mass

    def getPayloadCog(self) -> list[float]:
        ur = self._ur.received()
        return list(ur.payload_cog)

    def isConnected(self) -> bool:
        return self._ur.receive_connected

    def disconnect(self) -> None:
        return None


class DashboardClient:
    """Fake of ``dashboard_client.DashboardClient`` (the methods the bridge uses)."""

    def __init__(self, hostname: str, port: int = 29999, verbose: bool = False) -> None:
        self._host = hostname
        self._ur: FakeUR | None = None

    def connect(self, timeout_ms: int = 2000) -> None:
        self._ur = _server(self._host)

    def isConnected(self) -> bool:
        return self._ur is not None and self._ur.connected

    def polyscopeVersion(self) -> str:
        if self._ur is None:
            raise RuntimeError("Please connect before calling polyscopeVersion()")
        return self._ur.version

    def disconnect(self) -> None:
        self._ur = None
