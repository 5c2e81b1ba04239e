"""The robot-IO seam: what the controller reads from and writes to a robot, once per period.

One small typed contract between the 500 Hz loop and a robot, modelled on ros2_control's
``read(time, period)`` / ``write(time, period)`` cycle. Three implementations sit behind it
(:data:`langenv.robot.backends.ROBOT_BACKENDS`): MuJoCo (:mod:`langenv.robot.sim_io`), a real UR
through ``ur-rtde`` (:mod:`langenv.robot.ur.bridge`), and that same bridge over a fake of
``ur-rtde``'s two classes for tests (:mod:`langenv.robot.ur.fake_rtde`).

## The contract (:class:`RobotIO`)

All vectors are in the robot's **base frame** (z up), SI units.

| member | units, frame | timing |
|---|---|---|
| ``period`` | s (0.002 at 500 Hz) | fixed for the connection |
| ``joint_names``, ``joint_limits`` | names; (lower, upper) (n,) rad | fixed (the monitor's joint margin) |
| ``read() -> RobotState`` | see :class:`RobotState` | the state at the start of the current period; cheap, never blocks longer than the link's own latency |
| ``write_speed(xd, acceleration, time) -> sent`` | ``xd`` (6,): TCP linear (m/s) and angular (rad/s) velocity; ``acceleration`` m/s^2; ``time`` s | returns at once with the (6,) command actually sent, after the robot's own speed clip (``max_speed``); the robots here command no rotation (zeros in ``sent``): the orientation is held |
| ``wait() -> late`` | s | blocks until the next period starts; returns how late (s) that start is against the schedule (0 when on time). A late start re-bases the schedule: no bursts of catch-up periods |
| ``zero_ft_sensor()`` | | zeroes the wrist force/torque reading (the arm at rest) |
| ``stop()`` | | ``speedStop``: decelerate to rest and command nothing more (latched: ``write_speed`` then sends nothing and returns zeros); safe to call at any time, any number of times |
| ``enable()`` | | allow commands again (a new session, the operator having confirmed); a new robot starts stopped |
| ``close()`` | | release the link (after ``stop()``) |

Leaving a ``with`` block (:class:`RobotContext`) always runs ``stop()`` then ``close()``, whatever
raised. ``read``/``write_speed``/``wait`` raise :class:`~langenv.errors.DeviceError` when the link
is lost; the loop turns that into the ``connection_lost`` stop.

## Faults and the stops they cause

The loop (:class:`langenv.robot.io_arm.IOArm` under :class:`langenv.motion.tick.GuidedArm`) ends a
session on the first of these, always with ``stop()`` (``speedStop``) in the same period and the
speech faded out; the stop's name is in :data:`langenv.robot.safety.STOP_LIMITS` or
:data:`langenv.robot.safety.ROBOT_STOPS`:

| fault | detected by | stop |
|---|---|---|
| hand faster than ``max_speed + speed_tolerance`` | our monitor | ``speed`` |
| hand farther than ``max_deviation`` from the path | our monitor | ``path_deviation`` |
| force on the handle above ``max_force`` | our monitor | ``force`` |
| a joint within ``joint_margin`` of its range's end | our monitor | ``joint_limit`` |
| the robot's own protective stop | ``RobotState.protective_stop`` | ``robot_protective_stop`` |
| emergency stop pressed | ``RobotState.emergency_stop`` | ``emergency_stop`` |
| the robot's control program no longer runs | ``RobotState.program_running`` | ``program_stopped`` |
| a period starting more than 2 periods late | ``wait()`` | ``late_period`` |
| link lost (an exception from the link, or ``RobotState`` no longer fresh) | ``read``/``write_speed``/``wait`` | ``connection_lost`` |
| the force/torque reading bit-for-bit unchanged for ``stuck_after`` s | :class:`~langenv.robot.io_arm.IOArm` | ``sensor_stuck`` |
| a non-finite velocity command (a controller bug) | :class:`~langenv.robot.io_arm.IOArm` | ``bad_command`` |
| the speech's audio sink died (its thread or stream) | the session loop | ``audio_lost`` |
| Ctrl-C | the session loop | ``interrupted`` |
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from types import TracebackType
from typing import Protocol, runtime_checkable

import numpy as np
from numpy.typing import ArrayLike, NDArray

from langenv.errors import DeviceError
from langenv.validation import frozen_vector

__all__ = ["RobotContext", "RobotIO", "RobotState", "limit_speed"]


def _vector(value: ArrayLike, name: str, n: int | None) -> NDArray[np.float64]:
    return frozen_vector(value, f"RobotState.{name}", DeviceError, n)


@dataclass(frozen=True, eq=False)
class RobotState:
    """What the robot reports at the start of one control period (base frame, SI).

    Attributes:
        time: The robot's clock (s), increasing.
        tcp_pose: TCP position (m) and orientation as a rotation vector (rad), shape (6,).
        tcp_velocity: TCP linear (m/s) and angular (rad/s) velocity, shape (6,).
        joints: Joint positions (rad), shape (n,) (6 on a UR).
        wrench: Force (N) and torque (N m) at the TCP from the wrist sensor, shape (6,): what the
            person applies at the handle (zeroed at rest by ``zero_ft_sensor``).
        protective_stop: The robot is in its own protective stop.
        emergency_stop: An emergency stop is active.
        program_running: The robot's control program (the one that executes ``speedL``) runs.

    Raises:
        DeviceError: an array of the wrong shape or with a NaN or infinite value (the field named).
    """

    time: float
    tcp_pose: NDArray[np.float64]
    tcp_velocity: NDArray[np.float64]
    joints: NDArray[np.float64]
    wrench: NDArray[np.float64]
    protective_stop: bool = False
    emergency_stop: bool = False
    program_running: bool = True

    def __post_init__(self) -> None:
        if not math.isfinite(self.time):
            raise DeviceError(f"RobotState.time must be finite, got {self.time!r}")
        object.__setattr__(self, "time", float(self.time))
        object.__setattr__(self, "tcp_pose", _vector(self.tcp_pose, "tcp_pose", 6))
        object.__setattr__(self, "tcp_velocity", _vector(self.tcp_velocity, "tcp_velocity", 6))
        object.__setattr__(self, "joints", _vector(self.joints, "joints", None))
        object.__setattr__(self, "wrench", _vector(self.wrench, "wrench", 6))
        for name in ("protective_stop", "emergency_stop", "program_running"):
            object.__setattr__(self, name, bool(getattr(self, name)))

    @property
    def position(self) -> NDArray[np.float64]:
        """TCP position, shape (3,), m (a view)."""
        return self.tcp_pose[:3]

    @property
    def force(self) -> NDArray[np.float64]:
        """Force at the TCP, shape (3,), N (a view)."""
        return self.wrench[:3]


@runtime_checkable
class RobotIO(Protocol):
    """A robot the 500 Hz loop can drive (the contract: see this module's docstring)."""

    @property
    def period(self) -> float:
        """Control period (s)."""
        ...

    @property
    def joint_names(self) -> tuple[str, ...]:
        """Names of the joints, base to wrist."""
        ...

    @property
    def joint_limits(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Lower and upper ends of the joints' ranges, shape (n,) each (rad)."""
        ...

    def read(self) -> RobotState:
        """The state at the start of the current period."""
        ...

    def write_speed(
        self, xd: NDArray[np.float64], acceleration: float, time: float
    ) -> NDArray[np.float64]:
        """Command a TCP velocity ``xd`` (6,) (``speedL``); returns the (6,) command sent."""
        ...

    def wait(self) -> float:
        """Block until the next period starts; returns its lateness (s)."""
        ...

    def zero_ft_sensor(self) -> None:
        """Zero the wrist force/torque reading (the arm at rest)."""
        ...

    def stop(self) -> None:
        """Decelerate to rest (``speedStop``) and command nothing more (latched)."""
        ...

    def enable(self) -> None:
        """Allow commands again after :meth:`stop` (or construction)."""
        ...

    def close(self) -> None:
        """Release the link."""
        ...


class RobotContext:
    """``with robot: ...`` for a :class:`RobotIO`: leaving the block always stops, then closes."""

    def stop(self) -> None:  # pragma: no cover - overridden
        raise NotImplementedError

    def close(self) -> None:  # pragma: no cover - overridden
        raise NotImplementedError

    def __enter__(self) -> RobotContext:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        try:
            self.stop()
        finally:
            self.close()


def limit_speed(xd: NDArray[np.float64], max_speed: float) -> NDArray[np.float64]:
    """``xd`` (6,) with its linear part scaled down to at most ``max_speed`` (m/s); a non-finite
    command becomes rest. The robot-side clip every :class:`RobotIO` applies before sending;
    checks nothing else (hot path)."""
    v0, v1, v2, w0, w1, w2 = xd.tolist()
    s2 = v0 * v0 + v1 * v1 + v2 * v2
    if not (s2 < math.inf and math.isfinite(w0 + w1 + w2)):
        return np.zeros(6)
    if s2 > max_speed * max_speed:
        k = max_speed / math.sqrt(s2)
        v0, v1, v2 = v0 * k, v1 * k, v2 * k
    return np.array((v0, v1, v2, w0, w1, w2))
