"""IOArm: the arm :class:`~langenv.motion.tick.GuidedArm` drives, over any :class:`RobotIO`.

:class:`GuidedArm` was written against MuJoCo's :class:`~langenv.robot.arm.Arm` (``reset``,
``hand_position``, ``hand_velocity``, ``joint_positions``, ``step(v, f_ext)``). :class:`IOArm`
offers the same face over a robot: ``step`` sends the tick's velocity command (``speedL``), waits
for the next period and reads the new state, so the controller, the guide, the safety limits and
monitor, the speech and the policy run unchanged (in Python: the compiled tick is MuJoCo's own).
It also watches what only a real robot can do wrong (the fault table of :mod:`langenv.robot.io`)
and turns it into a named stop (:attr:`fault`), sending ``stop()`` in the same period.

:class:`MeasuredUser` is the person on a real robot: their force is what the wrist sensor reads.
"""

from __future__ import annotations

import math
import time as _time
from array import array

import numpy as np
from numpy.typing import ArrayLike, NDArray

from langenv.errors import ConfigError, DeviceError
from langenv.robot.io import RobotIO, RobotState
from langenv.robot.safety import SafetyStop
from langenv.validation import finite_positive

__all__ = ["LATE_PERIODS", "IOArm", "MeasuredUser"]

LATE_PERIODS = 2.0
"""A period that starts more than this many periods late stops the session (``late_period``)."""


class IOArm:
    """The arm's face for :class:`~langenv.motion.tick.GuidedArm`, over a :class:`RobotIO`.

    Args:
        robot: The robot (its ``period`` is the tick).
        acceleration: The ``acceleration`` passed with each ``speedL`` (m/s^2), > 0: how fast the
            robot follows a change of command. The command itself already changes at most at the
            admittance's ``max_acceleration`` except where the safety limits cut it.
        start_tolerance: How far (m) the TCP may be from the exercise's start at :meth:`reset`.
        stuck_after: A force/torque reading unchanged, bit for bit, for this long (s) stops the
            session (``sensor_stuck``): a live sensor always has some noise.

    Attributes:
        fault: The stop that halted the robot: a robot-side one (see
            :data:`langenv.robot.safety.ROBOT_STOPS`), or the monitor's (:meth:`stop_for`); None
            while it runs.
        compute_s: Per period, the loop's compute time (s, wall clock): from the end of
            ``wait()`` to the start of the next (read, control, speech, policy, logging,
            ``speedL``); what the period's deadline sees, preemption included.
        compute_cpu_s: The same span in the thread's CPU time (s): what the code costs, without
            the time other processes took the core.
        sent: The last command sent, shape (6,) (m/s, rad/s).
    """

    def __init__(
        self,
        robot: RobotIO,
        *,
        acceleration: float = 1.0,
        start_tolerance: float = 0.01,
        stuck_after: float = 0.25,
    ) -> None:
        if not isinstance(robot, RobotIO):
            raise DeviceError(f"IOArm: robot must implement RobotIO, got {type(robot).__name__}")
        self.robot = robot
        self.dt: float = finite_positive("IOArm: robot.period", robot.period, DeviceError)
        self.acceleration = finite_positive("IOArm.acceleration", acceleration, ConfigError)
        self.start_tolerance = finite_positive(
            "IOArm.start_tolerance", start_tolerance, ConfigError
        )
        self._stuck_periods = max(
            1, round(finite_positive("IOArm.stuck_after", stuck_after, ConfigError) / self.dt)
        )
        lo, hi = robot.joint_limits
        self._lo, self._hi = np.array(lo, np.float64), np.array(hi, np.float64)
        self.joint_names: tuple[str, ...] = tuple(robot.joint_names)
        self.max_hand_speed: float = 0.5
        self.fault: SafetyStop | None = None
        self._latched: SafetyStop | None = None
        self.compute_s = array("d")
        self.compute_cpu_s = array("d")
        self.sent = np.zeros(6)
        self.time = 0.0
        self._state: RobotState = robot.read()
        self._wrench: list[float] = []
        self._same = 0
        self._armed = False
        self._t_start = _time.perf_counter()
        self._cpu_start = _time.thread_time()

    # ------------------------------------------------------------------ Arm's face
    @property
    def joint_range(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Lower and upper ends of the joints' ranges, shape (n,) each (rad)."""
        return self._lo.copy(), self._hi.copy()

    @property
    def state(self) -> RobotState:
        """The state read at the start of the current period."""
        return self._state

    def reset(self, hand_position: ArrayLike | None = None) -> None:
        """Start a session with the TCP at ``hand_position`` (the exercise's start).

        Unlike the simulation, a robot is not placed: it must already be there (the confirmed
        move of :mod:`langenv.live.ur_preflight`). Clears the fault and the timing record; the
        first :meth:`step` allows commands again (``robot.enable()``, which starts the robot's
        period clock right before the first command). A stop is latched across sessions: after
        one, a new session needs the operator's :meth:`release` first.

        Raises:
            DeviceError: a stop ended the last session and was not released, or the TCP is more
                than ``start_tolerance`` from ``hand_position``.
        """
        if self._latched is not None:
            raise DeviceError(
                f"a stop ended the last session ({self._latched.message}): a new one needs the "
                "operator's confirmation (IOArm.release())"
            )
        self._state = self.robot.read()
        if hand_position is not None:
            gap = float(np.linalg.norm(self._state.position - np.asarray(hand_position, float)))
            if gap > self.start_tolerance:
                raise DeviceError(
                    f"the TCP is {gap * 1e3:.1f} mm from the exercise's start (tolerance "
                    f"{self.start_tolerance * 1e3:.0f} mm): move it there first (preflight)"
                )
        self.fault = None
        self.time = 0.0
        self.compute_s = array("d")
        self.compute_cpu_s = array("d")
        self._wrench = self._state.wrench.tolist()
        self._same = 0
        self.sent = np.zeros(6)
        self._armed = False

    def hand_position(self) -> NDArray[np.float64]:
        """TCP position, shape (3,), m (a new array)."""
        return self._state.tcp_pose[:3].copy()

    def hand_velocity(self) -> NDArray[np.float64]:
        """TCP linear velocity, shape (3,), m/s (a new array)."""
        return self._state.tcp_velocity[:3].copy()

    def joint_positions(self) -> NDArray[np.float64]:
        """Joint positions, shape (n,), rad (a new array)."""
        return self._state.joints.copy()

    def measured_force(self) -> NDArray[np.float64]:
        """Force the wrist sensor reads, shape (3,), N (a new array)."""
        return self._state.wrench[:3].copy()

    def step(self, v_ref: NDArray[np.float64], f_ext: NDArray[np.float64]) -> None:
        """Send ``v_ref`` (3,) m/s as ``speedL`` (no rotation), wait for the next period, read.

        ``f_ext`` is ignored: on a robot the person pushes the arm itself. After a fault nothing
        is sent. A non-finite ``v_ref`` is the ``bad_command`` stop; nothing else of the
        arguments is checked (hot path: GuidedArm's command is limited).
        """
        if self.fault is not None:
            return
        robot = self.robot
        v0, v1, v2 = v_ref.tolist()
        if not math.isfinite(v0 + v1 + v2):  # a controller bug: stop, never "rest" and go on
            self._halt("bad_command", 0.0, 0.0, f"velocity command {[v0, v1, v2]} m/s")
            return
        try:
            if not self._armed:
                robot.enable()
                self._armed = True
                self._t_start = _time.perf_counter()
                self._cpu_start = _time.thread_time()
            self.sent = robot.write_speed(
                np.array((v0, v1, v2, 0.0, 0.0, 0.0)), self.acceleration, self.dt
            )
            self.compute_s.append(_time.perf_counter() - self._t_start)
            self.compute_cpu_s.append(_time.thread_time() - self._cpu_start)
            late = robot.wait()
            self._t_start = _time.perf_counter()
            self._cpu_start = _time.thread_time()
            state = robot.read()
        except DeviceError as exc:
            self._halt("connection_lost", 0.0, 0.0, str(exc))
            return
        self.time += self.dt
        self._state = state
        self._check(state, late)

    def _check(self, state: RobotState, late: float) -> None:
        """The robot-side faults of this period's state, in the order of the fault table."""
        if state.emergency_stop:
            self._halt("emergency_stop")
        elif state.protective_stop:
            self._halt("robot_protective_stop")
        elif not state.program_running:
            self._halt("program_stopped")
        elif late > LATE_PERIODS * self.dt:
            self._halt("late_period", late, LATE_PERIODS * self.dt)
        else:
            wrench = state.wrench.tolist()
            self._same = self._same + 1 if wrench == self._wrench else 0
            self._wrench = wrench
            if self._same >= self._stuck_periods:
                self._halt("sensor_stuck", self._same * self.dt, self._stuck_periods * self.dt)

    def stop_for(self, stop: SafetyStop) -> None:
        """Our monitor's protective stop (``stop``): ``stop()`` is sent now, in the period that
        found it, and nothing after (:attr:`fault` becomes ``stop``)."""
        if self.fault is None:
            self.fault = stop
        self._halt(stop.limit)

    def release(self) -> None:
        """The operator confirms a new session after a stop (see :meth:`reset`)."""
        self._latched = None

    def halt(self, limit: str, detail: str = "") -> None:
        """Stop now for a reason found outside the arm (``interrupted``): ``stop()`` is sent."""
        self._halt(limit, 0.0, 0.0, detail)

    def _halt(
        self, limit: str, value: float = 0.0, threshold: float = 0.0, detail: str = ""
    ) -> None:
        if self.fault is None:
            self.fault = SafetyStop(limit, value, threshold, self.time, detail)
        self._latched = self.fault
        try:
            self.robot.stop()
        except DeviceError:
            pass  # the link is gone: the robot's own watchdog stops it

    def close(self) -> None:
        """Nothing: the robot's link is closed by whoever opened it."""


class MeasuredUser:
    """The person on a real robot: the force is what the wrist sensor measures.

    Args:
        arm: The arm whose sensor it reads.
    """

    def __init__(self, arm: IOArm) -> None:
        self.arm = arm

    def reset(self, rng: np.random.Generator) -> None:
        """Nothing to draw: the person is real."""

    def force(
        self, t: float, hand_velocity: NDArray[np.float64], tangent: NDArray[np.float64]
    ) -> NDArray[np.float64]:
        """The measured force on the handle, shape (3,), N."""
        return self.arm.measured_force()
