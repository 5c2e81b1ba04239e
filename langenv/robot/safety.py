"""Safety limits of the arm and the protective stop, modelled on a UR5's safety functions.

A UR5 (CB series) keeps its tool within configured limits in two ways: its controller never
*commands* motion beyond them, and an independent safety system *monitors* the actual values and
makes a **protective stop** when one is exceeded anyway (the arm halts and holds; the program
stops). LangCtrl does the same at every 2 ms tick:

Commanded (:func:`limit_velocity`, applied to the admittance's reference velocity):

* the hand's speed is at most ``max_speed`` (also the arm's Cartesian command limit);
* beyond ``hold_deviation`` from the path the arm commands no motion away from it (within
  ``HOLD_TIME`` s of it, the outward speed tapers to 0), like a UR5 slowing down for a safety plane.

Monitored (:class:`SafetyMonitor`), a breach being a protective stop:

* ``speed``: the measured hand speed exceeds ``max_speed + speed_tolerance``;
* ``path_deviation``: the hand is more than ``max_deviation`` from the path (``|x - T(s)|``, ``s``
  the guide's closest point);
* ``force``: the force on the handle exceeds ``max_force`` (a UR5's default force limit, 150 N);
* ``joint_limit``: a joint is within ``joint_margin`` of the end of its range.

A person can push the hand beyond what the controller commands (the force acts on the arm's
links); the monitor is what catches that.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, fields

import numpy as np
from numpy.typing import NDArray

from langenv.errors import ConfigError
from langenv.layout import field_table

__all__ = [
    "DEFAULT_MAX_SPEED",
    "HOLD_TIME",
    "JOINT_CHECK_MAX",
    "JOINT_SPEED_BOUND",
    "MONITOR_STATE",
    "ROBOT_STOPS",
    "SAFETY_SETTINGS",
    "STOP_LIMITS",
    "SafetyLimits",
    "SafetyMonitor",
    "SafetyStop",
    "limit_velocity",
]

DEFAULT_MAX_SPEED = 0.5
"""Default TCP speed limit (m/s): the arm's velocity command limit."""

MONITOR_STATE = field_table(
    """
    countdown:int  ticks until the joints are checked again
    """
)
"""The monitor's state (:attr:`SafetyMonitor.countdown`), declared for the compiled tick."""
SAFETY_SETTINGS = field_table(
    """
    hold                   ``hold_deviation``: no command away from the path beyond it (m)
    v_max                  ``max_speed``: the command's speed limit (m/s)
    f_max                  the force limit (N)
    d_max                  the path deviation limit (m)
    v_trip                 the measured speed that trips a stop (m/s)
    per_tick               the most a joint moves in a tick (rad)
    has_joint_limits:bool  whether any joint is limited
    n_joints:int           the joints watched (their bounds follow the legs)
    """
)
"""The safety layer's settings (:meth:`SafetyMonitor.settings`)."""

HOLD_TIME = 0.05
"""Time constant (s) of the taper of outward motion near ``hold_deviation``: the outward command
speed is at most ``(hold_deviation - d) / HOLD_TIME``."""

JOINT_SPEED_BOUND = 4.0 * math.pi
"""Joint speed (rad/s or m/s) no joint is assumed to exceed: twice the UR5's limit, far above
what a hand within the speed limit needs."""

JOINT_CHECK_MAX = 25
"""Most ticks between two joint-limit checks."""

STOP_LIMITS: tuple[str, ...] = ("speed", "path_deviation", "force", "joint_limit")
"""Names of the limits whose breach is a protective stop (``info["safety_stop"]``)."""

ROBOT_STOPS: tuple[str, ...] = (
    "robot_protective_stop",
    "emergency_stop",
    "program_stopped",
    "late_period",
    "connection_lost",
    "sensor_stuck",
    "bad_command",
    "audio_lost",
    "interrupted",
)
"""Names of the stops a real robot's loop adds to :data:`STOP_LIMITS` (:mod:`langenv.robot.io`):
the robot's own protective and emergency stops, its control program no longer running, a control
period started more than two periods late, the link to the robot lost, the force sensor's reading
frozen, a non-finite velocity command from the controller (a bug), the speech's audio output dead
(the person is no longer talked through), and the operator's Ctrl-C."""

_UNITS = {
    "speed": "m/s",
    "path_deviation": "m",
    "force": "N",
    "joint_limit": "rad",
    "late_period": "s",
    "sensor_stuck": "s",
}
_WHAT = {
    "speed": "hand speed",
    "path_deviation": "distance from the path",
    "force": "force on the handle",
    "joint_limit": "joint",
    "robot_protective_stop": "the robot made a protective stop of its own",
    "emergency_stop": "the robot's emergency stop is pressed",
    "program_stopped": "the robot's control program stopped running",
    "late_period": "control period started late by",
    "connection_lost": "the link to the robot is lost",
    "sensor_stuck": "force sensor reading unchanged for",
    "bad_command": "the controller's velocity command is not finite",
    "audio_lost": "the speech's audio output stopped",
    "interrupted": "interrupted by the operator (Ctrl-C)",
}


@dataclass(frozen=True)
class SafetyLimits:
    """The arm's safety limits (defaults fit a therapy exercise).

    Args:
        max_speed: TCP speed limit (m/s), > 0: the arm never commands a faster hand.
        speed_tolerance: Measured speed above ``max_speed + speed_tolerance`` (m/s) is a
            protective stop, >= 0.
        max_deviation: Largest distance of the hand from the path (m), > 0; beyond it, a
            protective stop.
        hold_deviation: Distance from the path (m) beyond which the arm commands no motion away
            from it, in ``(0, max_deviation]``.
        max_force: Largest force on the handle (N), > 0; beyond it, a protective stop.
        joint_margin: A joint closer than this (rad or m) to the end of its range is a protective
            stop, >= 0.

    Raises:
        ConfigError: a field that is not a finite number in its range (names the field).
    """

    max_speed: float = DEFAULT_MAX_SPEED
    speed_tolerance: float = 0.025
    max_deviation: float = 0.10
    hold_deviation: float = 0.08
    max_force: float = 150.0
    joint_margin: float = 0.01

    def __post_init__(self) -> None:
        for f in fields(self):
            value = getattr(self, f.name)
            if isinstance(value, bool) or not isinstance(value, int | float):
                raise ConfigError(
                    f"SafetyLimits.{f.name} must be a number, got {type(value).__name__}"
                )
            if not math.isfinite(value):
                raise ConfigError(f"SafetyLimits.{f.name} must be finite, got {value!r}")
            object.__setattr__(self, f.name, float(value))
        for name in ("max_speed", "max_deviation", "hold_deviation", "max_force"):
            if getattr(self, name) <= 0.0:
                raise ConfigError(f"SafetyLimits.{name} must be > 0, got {getattr(self, name)}")
        for name in ("speed_tolerance", "joint_margin"):
            if getattr(self, name) < 0.0:
                raise ConfigError(f"SafetyLimits.{name} must be >= 0, got {getattr(self, name)}")
        if self.hold_deviation > self.max_deviation:
            raise ConfigError(
                f"SafetyLimits.hold_deviation must be <= max_deviation={self.max_deviation}, "
                f"got {self.hold_deviation}"
            )


@dataclass(frozen=True)
class SafetyStop:
    """A protective stop: which limit was exceeded, by how much, and when.

    Attributes:
        limit: One of :data:`STOP_LIMITS`, or on a real robot one of :data:`ROBOT_STOPS`.
        value: The measured value (m/s, m, N; for ``joint_limit`` the joint's distance to the
            end of its range, rad or m; for ``late_period`` the lateness, for ``sensor_stuck`` how
            long the reading stayed the same, s; 0 for the other robot stops).
        threshold: The limit it crossed (same unit).
        time: Time of the tick (s since the episode started).
        detail: What exceeded it, in words (e.g. the joint's name).
    """

    limit: str
    value: float
    threshold: float
    time: float
    detail: str = ""

    @property
    def message(self) -> str:
        """One line saying why the arm stopped."""
        what = _WHAT[self.limit] + (f" {self.detail}" if self.detail else "")
        if self.limit in ROBOT_STOPS:
            if self.limit not in _UNITS:
                return f"stop at t={self.time:.3f} s: {what}"
            return (
                f"stop at t={self.time:.3f} s: {what} {self.value:.4g} s (limit "
                f"{self.threshold:g} s)"
            )
        unit = _UNITS[self.limit]
        if self.limit == "joint_limit":
            return (
                f"protective stop at t={self.time:.3f} s: {what} is {self.value:.4g} {unit} from "
                f"the end of its range (margin {self.threshold:g} {unit})"
            )
        return (
            f"protective stop at t={self.time:.3f} s: {what} {self.value:.4g} {unit} exceeds "
            f"the {self.threshold:g} {unit} limit"
        )


def limit_velocity(
    v: NDArray[np.float64], offset: Sequence[float], limits: SafetyLimits
) -> NDArray[np.float64]:
    """The commanded hand velocity within the limits (speed, and no motion away from the path
    beyond ``hold_deviation``).

    Args:
        v: Reference velocity, shape (3,), m/s.
        offset: Hand position minus its closest path point ``x - T(s)``, three floats, m.
        limits: The limits.

    Returns:
        ``v`` itself when it is within the limits, else a new (3,) array: the outward component
        (along ``offset``) reduced to at most ``max(0, (hold_deviation - |offset|) / HOLD_TIME)``,
        then the whole scaled down to ``max_speed``.
    """
    v0, v1, v2 = v.tolist()
    o0, o1, o2 = offset
    vmax = limits.max_speed
    d2 = o0 * o0 + o1 * o1 + o2 * o2
    free = limits.hold_deviation - vmax * HOLD_TIME  # closer to the path no cap can apply
    changed = False
    if not (free > 0.0 and d2 <= free * free):
        d = math.sqrt(d2)
        out = (v0 * o0 + v1 * o1 + v2 * o2) / d if d > 0.0 else 0.0
        cap = max((limits.hold_deviation - d) / HOLD_TIME, 0.0)
        if out > cap:
            k = (out - cap) / d
            v0, v1, v2 = v0 - k * o0, v1 - k * o1, v2 - k * o2
            changed = True
    s2 = v0 * v0 + v1 * v1 + v2 * v2
    if s2 > vmax * vmax:
        k = vmax / math.sqrt(s2)
        v0, v1, v2 = v0 * k, v1 * k, v2 * k
        changed = True
    return np.array((v0, v1, v2)) if changed else v


class SafetyMonitor:
    """Checks one tick's measurements against the limits; the first breach is a protective stop.

    The joints are checked every tick while one is within ``JOINT_CHECK_MAX`` ticks of its margin
    at :data:`JOINT_SPEED_BOUND`, and at least every ``JOINT_CHECK_MAX`` ticks otherwise.

    Args:
        limits: The limits.
        dt: The tick (s), > 0.
        joint_lower: Lower ends of the controlled joints' ranges, shape (n,) (``-inf``: none).
        joint_upper: Upper ends, shape (n,) (``inf``: none).
        joint_names: Names of the joints (for the stop's message).

    Raises:
        ConfigError: ``limits`` is not a :class:`SafetyLimits`, ``dt`` is not > 0, or the joint
            arrays disagree.
    """

    def __init__(
        self,
        limits: SafetyLimits,
        dt: float,
        joint_lower: NDArray[np.float64] | None = None,
        joint_upper: NDArray[np.float64] | None = None,
        joint_names: tuple[str, ...] = (),
    ) -> None:
        if not isinstance(limits, SafetyLimits):
            raise ConfigError(
                f"SafetyMonitor: limits must be SafetyLimits, got {type(limits).__name__}"
            )
        if not (math.isfinite(dt) and dt > 0.0):
            raise ConfigError(f"SafetyMonitor: dt must be finite and > 0, got {dt!r}")
        self.limits = limits
        lo = np.array([] if joint_lower is None else joint_lower, dtype=np.float64)
        hi = np.array([] if joint_upper is None else joint_upper, dtype=np.float64)
        if lo.shape != hi.shape or lo.ndim != 1:
            raise ConfigError(
                f"SafetyMonitor: joint ranges must be 1-D of equal length, got {lo.shape}, "
                f"{hi.shape}"
            )
        self._lo, self._hi = lo, hi
        m = limits.joint_margin
        self._bounds = [(float(a) + m, float(b) - m) for a, b in zip(lo, hi, strict=True)]
        self._has_joint_limits = bool(np.any(np.isfinite(lo)) or np.any(np.isfinite(hi)))
        self._names = joint_names
        self._per_tick = JOINT_SPEED_BOUND * dt
        self._countdown = 0
        self._f_max = limits.max_force
        self._d_max = limits.max_deviation
        self._v_trip = limits.max_speed + limits.speed_tolerance

    def reset(self) -> None:
        """Check the joints at the next tick."""
        self._countdown = 0

    @property
    def countdown(self) -> int:
        """Ticks until the joints are checked again (:data:`MONITOR_STATE`)."""
        return self._countdown

    @countdown.setter
    def countdown(self, value: int) -> None:
        self._countdown = int(value)

    def settings(self) -> dict[str, float]:
        """The monitor's and the command limits' settings by the names of
        :data:`SAFETY_SETTINGS`."""
        lim = self.limits
        return {
            "hold": lim.hold_deviation, "v_max": lim.max_speed, "f_max": self._f_max,
            "d_max": self._d_max, "v_trip": self._v_trip, "per_tick": self._per_tick,
            "has_joint_limits": self._has_joint_limits, "n_joints": len(self._bounds),
        }  # fmt: skip

    def bounds(self) -> np.ndarray:
        """Each joint's range less the margin, flat: ``lower_0, upper_0, lower_1, ...`` (rad)."""
        return np.asarray(self._bounds, dtype=np.float64).reshape(-1)

    def check(
        self,
        time: float,
        speed: float,
        deviation: float,
        force: float,
        joints: Callable[[], NDArray[np.float64]] | None = None,
    ) -> SafetyStop | None:
        """The protective stop these measurements call for, if any.

        Args:
            time: Time of the tick (s).
            speed: Measured hand speed (m/s).
            deviation: Distance of the hand from the path (m).
            force: Magnitude of the force on the handle (N).
            joints: Returns the joint positions, shape (n,) (rad or m), when the joints are due
                for a check; None skips them.

        Returns:
            The stop (force, then path deviation, speed, joint limit, when several are
            exceeded), or None when every value is within its limit. A NaN measurement is a
            breach.
        """
        if not force <= self._f_max:
            return SafetyStop("force", force, self._f_max, time)
        if not deviation <= self._d_max:
            return SafetyStop("path_deviation", deviation, self._d_max, time)
        if not speed <= self._v_trip:
            return SafetyStop("speed", speed, self._v_trip, time)
        if joints is not None and self._has_joint_limits:
            self._countdown -= 1
            if self._countdown <= 0:
                return self._check_joints(time, joints())
        return None

    def _check_joints(self, time: float, q: NDArray[np.float64]) -> SafetyStop | None:
        slack = math.inf
        for qi, (lo, hi) in zip(q.tolist(), self._bounds, strict=True):
            room = min(qi - lo, hi - qi)
            if not room >= 0.0:
                rooms = np.minimum(q - self._lo, self._hi - q)
                j = int(np.argmin(rooms))
                name = self._names[j] if j < len(self._names) else f"#{j}"
                m = self.limits.joint_margin
                return SafetyStop("joint_limit", float(rooms[j]), m, time, name)
            slack = min(slack, room)
        self._countdown = max(1, min(JOINT_CHECK_MAX, int(slack / self._per_tick)))
        return None
