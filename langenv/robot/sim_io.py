"""MujocoRobot: the simulated UR5 (:class:`~langenv.robot.arm.Arm`) behind the robot-IO seam.

A thin wrapper: ``write_speed`` stores the command, ``wait`` is one physics step of the arm's
velocity controller C with the simulated person's force on the handle, ``read`` reports the
handle site. ``LangCtrl-v0``'s own 500 Hz path does not go through it (its compiled ticks call
MuJoCo directly); it is how the robot loop (:mod:`langenv.robot.io_arm`) and any code written
against :class:`~langenv.robot.io.RobotIO` run on the simulation.
"""

from __future__ import annotations

import time as _time
from collections.abc import Callable

import mujoco
import numpy as np
from numpy.typing import NDArray

from langenv.errors import ConfigError
from langenv.robot.arm import Arm
from langenv.robot.io import RobotContext, RobotState, limit_speed
from langenv.robot.rotation import rotation_vector

__all__ = ["MujocoRobot", "Person"]

Person = Callable[[float, NDArray[np.float64]], NDArray[np.float64]]
"""``f(t, tcp_velocity) -> force``: a simulated person's force on the handle, (3,) N, from the
time (s) and the TCP's linear velocity (3,) m/s."""


class MujocoRobot(RobotContext):
    """The MuJoCo arm as a :class:`~langenv.robot.io.RobotIO`.

    Args:
        arm: The arm (default: our UR5, reset to its home pose).
        person: The simulated person's force on the handle (default: none); the wrist sensor
            reads it (``wrench``) plus its noise.
        max_speed: The robot-side TCP speed clip of ``write_speed`` (m/s).
        ft_noise: Standard deviation (N) of the wrist sensor's noise on each force axis (a live
            sensor is never bit-for-bit constant: the loop's stuck-sensor check relies on it).
        seed: Seed of the noise's generator.
        realtime: ``wait`` also sleeps until the period's end on the wall clock (a live
            session, ``langctrl play --robot mujoco``) and reports its lateness;
            otherwise the simulation runs as fast as it computes, never late.

    Angular velocity commands are ignored: the arm's controller holds the handle's orientation.
    """

    def __init__(
        self,
        arm: Arm | None = None,
        person: Person | None = None,
        max_speed: float = 0.5,
        ft_noise: float = 0.05,
        seed: int = 0,
        realtime: bool = False,
    ) -> None:
        if not max_speed > 0.0:
            raise ConfigError(f"MujocoRobot.max_speed must be > 0 m/s, got {max_speed!r}")
        if not ft_noise >= 0.0:
            raise ConfigError(f"MujocoRobot.ft_noise must be >= 0 N, got {ft_noise!r}")
        self.ft_noise = float(ft_noise)
        self.realtime = bool(realtime)
        self._due: float | None = None
        self._rng = np.random.default_rng(seed)
        self.arm = arm if arm is not None else Arm()
        self.person = person
        self.max_speed = float(max_speed)
        self._cmd = np.zeros(6)
        self._force = np.zeros(3)
        self._offset = np.zeros(3)
        self._enabled = False
        self.time = 0.0
        self._jacr = np.zeros((3, self.arm.model.nv))

    @property
    def period(self) -> float:
        """The arm's timestep (s)."""
        return self.arm.dt

    @property
    def joint_names(self) -> tuple[str, ...]:
        """The controlled joints."""
        return tuple(self.arm.joint_names)

    @property
    def joint_limits(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """The joints' ranges (rad)."""
        return self.arm.joint_range

    def read(self) -> RobotState:
        """The handle site's pose and velocity, the joints, the person's force as the wrench."""
        arm = self.arm
        rot = rotation_vector(np.eye(3), arm.hand_rotation())
        mujoco.mj_jacSite(arm.model, arm.data, None, self._jacr, arm.site_id)
        omega = self._jacr @ arm.data.qvel
        wrench = np.zeros(6)
        wrench[:3] = self._force - self._offset
        if self.ft_noise > 0.0:
            wrench[:3] += self._rng.normal(0.0, self.ft_noise, 3)
        return RobotState(
            self.time,
            np.concatenate((arm.hand_position(), rot)),
            np.concatenate((arm.hand_velocity(), omega)),
            arm.joint_positions(),
            wrench,
        )

    def write_speed(
        self, xd: NDArray[np.float64], acceleration: float, time: float
    ) -> NDArray[np.float64]:
        """Store the command for the next :meth:`wait` (speed-clipped); zeros once stopped."""
        if not self._enabled:
            return np.zeros(6)
        self._cmd = limit_speed(xd, self.max_speed)
        return self._cmd

    def wait(self) -> float:
        """One physics step under the stored command and the person's force; with
        ``realtime``, then sleep to the period's end (returns the lateness, s), else 0."""
        arm = self.arm
        if self.person is not None:
            self._force = np.asarray(self.person(self.time, arm.hand_velocity()), np.float64)
        arm.step(self._cmd[:3], self._force)
        self.time += arm.dt
        return self._sleep() if self.realtime else 0.0

    def _sleep(self) -> float:
        now = _time.perf_counter()
        due = (now if self._due is None else self._due) + self.arm.dt
        if now > due:  # late: re-base the schedule, no catch-up burst
            self._due = now
            return now - due
        while (left := due - _time.perf_counter()) > 0.0:
            _time.sleep(left - 0.0007 if left > 0.0007 else 0.0)  # then spin
        self._due = due
        return 0.0

    def zero_ft_sensor(self) -> None:
        """Subtract the current force from later readings."""
        self._offset = self._force.copy()

    def stop(self) -> None:
        """Command rest from now on (latched until :meth:`enable`)."""
        self._enabled = False
        self._cmd = np.zeros(6)

    def enable(self) -> None:
        """Accept commands (and restart the real-time schedule)."""
        self._enabled = True
        self._due = None

    def close(self) -> None:
        """Free the arm's renderer, if any."""
        self.arm.close()
