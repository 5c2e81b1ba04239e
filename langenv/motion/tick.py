"""The physical half of one 500 Hz control tick: arm, guide, admittance, sensor, cooperation, ETC.

:class:`GuidedArm` composes the parts of SPEC §1 (Fig. 2 of the paper) that act on the arm:

1. the person's force ``F_user`` acts on the handle and is measured by the force sensor (noise,
   soft deadband) as ``F~``;
2. the cooperation model ``Y_c`` filters ``|F~|`` into ``c``;
3. the guide finds the closest point ``x_d`` (locally), tracks the stops, and gives
   ``F_virtual = K (x_d - x) + F_prop b``;
4. the variable admittance ``A(p)`` turns ``F~ + F_virtual`` into ``v_ref``;
5. the velocity command sent to the robot follows ``v_ref`` (capped by the guide's speed
   governor while the person pushes the hand along) with at most ``max_acceleration`` (the ``a``
   of a UR's ``speedL``); once the last leg is done it brakes to 0 at that rate;
6. the safety layer limits ``v_ref`` and the command (speed; no motion away from the path beyond
   ``hold_deviation``, overriding the acceleration limit), the velocity controller ``C`` drives
   the hand to the command and MuJoCo steps the arm;
7. the motion ETC ``t_x`` is estimated from the new state;
8. the safety monitor checks the hand's speed and distance from the path, the force on the handle
   and the joints; a breach is a **protective stop** (:attr:`GuidedArm.safety_stop`): from then
   on the arm holds still (see :mod:`langenv.robot.safety`).

Motion is over when the command has come to rest after the last leg.

The paces ``p`` (and its rate) come from outside: they are the aligner's business.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from langenv import vec
from langenv.control.admittance import AdmittanceParams, VariableAdmittance
from langenv.control.command import cap_speed, follow
from langenv.control.cooperation import CooperationFilter
from langenv.control.guide import Guide, GuideState
from langenv.control.motion_etc import FastETC
from langenv.control.trajectory import Trajectory
from langenv.kernels import mjc
from langenv.motion.compiled_tick import CompiledTick
from langenv.motion.tick_kernels import TICK
from langenv.robot.arm import Arm
from langenv.robot.force_sensor import ForceSensor
from langenv.robot.io_arm import IOArm
from langenv.robot.safety import SafetyLimits, SafetyMonitor, SafetyStop, limit_velocity

__all__ = ["GuidedArm"]

_T = TICK.at
_GUIDE = TICK.span("s", "done")
_FILTER_TO_END = TICK.span("r", "t_end")  # r, c, t_x, time, t_end
_HAND = TICK.span("hand_speed", "path_deviation")


class GuidedArm:
    """A UR5 under the paper's variable admittance, guided along a trajectory.

    Args:
        arm: The simulated arm (its model's timestep is the tick, 2 ms), or a robot behind the
            robot-IO seam (:class:`~langenv.robot.io_arm.IOArm`: the Python tick; its faults
            are protective stops too, ahead of the monitor's).
        trajectory: The exercise path.
        params: Virtual dynamics and guide parameters.
        sensor: The handle's force sensor.
        cooperation: The cooperation filter.
        safety: Safety limits (default :class:`~langenv.robot.safety.SafetyLimits`); its
            ``max_speed`` becomes the arm's velocity command limit (``arm.max_hand_speed``).
        compiled: Run the tick as compiled code (:mod:`langenv.kernels`, the same operations in
            the same order: bit-identical results, about 5x faster; where MuJoCo's library
            cannot be called from compiled code, the Python parts run); ``False`` runs the
            Python parts themselves, the reference.
    """

    def __init__(
        self,
        arm: Arm | IOArm,
        trajectory: Trajectory,
        params: AdmittanceParams,
        sensor: ForceSensor,
        cooperation: CooperationFilter,
        safety: SafetyLimits | None = None,
        *,
        compiled: bool = True,
    ) -> None:
        self.arm = arm
        self.trajectory = trajectory
        self.params = params
        self.sensor = sensor
        self.coop = cooperation
        self.guide = Guide(trajectory, params)
        self.admittance = VariableAdmittance(params)
        self.etc = FastETC(self.guide, self.admittance)
        self.limits = safety if safety is not None else SafetyLimits()
        arm.max_hand_speed = self.limits.max_speed  # one source for the speed limit
        lo, hi = arm.joint_range
        self.monitor = SafetyMonitor(self.limits, arm.dt, lo, hi, arm.joint_names)
        self.safety_stop: SafetyStop | None = None
        """The protective stop that halted the arm, or None."""
        self.path_deviation: float = 0.0
        self._path_point: list[float] = trajectory.position(0.0).tolist()  # T(s), m
        """Hand's distance ``|x - T(s)|`` from its closest path point, after the last tick (m)."""
        self.dt: float = arm.dt
        self.state: GuideState = self.guide.initial_state()
        self._v_ref = np.zeros(3)
        self._v_cmd = np.zeros(3)
        self.f_user = np.zeros(3)
        self._f_measured = np.zeros(3)
        self.t_x: float = 0.0
        self.t_leg: float = 0.0
        """The motion's time to the current leg's switch (s; once done: the braking time)."""
        self._dv_max = params.max_acceleration * arm.dt
        self.t_motion_end: float | None = None
        self.time: float = 0.0
        self._hand_velocity = np.zeros(3)
        self._hand_speed = 0.0
        fast = compiled and isinstance(arm, Arm) and mjc.available()
        self._compiled: CompiledTick | None = CompiledTick(self) if fast else None
        if self._compiled is not None:
            self._compiled.load()

    # ------------------------------------------------------------------ compiled state
    @property
    def compiled_tick(self) -> CompiledTick | None:
        """The compiled tick (:class:`~langenv.motion.compiled_tick.CompiledTick`), or None where
        the Python parts tick (see ``compiled``)."""
        return self._compiled

    def tick_state(self) -> dict[str, Any]:
        """The state of the guided arm and its parts by the names of
        :data:`~langenv.motion.tick_kernels.TICK` (what the compiled tick starts from)."""
        st = self.state
        return {
            "s": st.s, "leg": st.leg, "done": st.done, "v_ref": self._v_ref,
            "v_cmd": self._v_cmd, "was_moving": bool(self._v_cmd.any()),
            "f_measured": self._f_measured, "r": self.coop.r, "c": self.coop.c, "t_x": self.t_x,
            "time": self.time,
            "t_end": math.nan if self.t_motion_end is None else self.t_motion_end,
            "path_point": self._path_point, "hand_velocity": self._hand_velocity,
            "hand_speed": self._hand_speed, "path_deviation": self.path_deviation,
            "countdown": self.monitor.countdown,
            "tangent": self.guide.tangent(st, self.arm.hand_position()), "t_leg": self.t_leg,
        }  # fmt: skip

    def tick_settings(self) -> dict[str, Any]:
        """The settings of the guided arm and its parts by the names of
        :data:`~langenv.motion.tick_kernels.TICK`."""
        return {
            **self.guide.settings(),
            **self.admittance.settings(),
            **self.coop.settings(self.dt),
            **self.monitor.settings(),
            "max_acc": self.params.max_acceleration,
            "dv_max": self._dv_max,
            "deadband": self.sensor.deadband,
            "dt": self.dt,
        }

    def take_tick_state(self, ws: np.ndarray) -> None:
        """Take the state the Python objects expose from the compiled tick's ``ws`` (after
        compiled ticks): guide state, cooperation, ``t_x``, time, the motion's end, hand speed
        and path deviation."""
        s, leg, done = ws[_GUIDE].tolist()
        st = self.state
        st.s, st.leg, st.done = s, int(leg), done != 0.0
        r, c, t_x, time, t_end = ws[_FILTER_TO_END].tolist()
        self.coop.r, self.coop.c = r, c
        self.t_x, self.time = t_x, time
        self.t_leg = float(ws[_T.t_leg])
        if t_end == t_end:  # not NaN
            self.t_motion_end = t_end
        self._hand_speed, self.path_deviation = ws[_HAND].tolist()

    def store_tick_state(self, ws: np.ndarray) -> None:
        """Take the rest of the state from ``ws`` (before a Python tick): the velocities, the
        sensor's reading, the path point, the hand's velocity and the monitor's countdown."""
        self._v_ref = ws[_T.v_ref : _T.v_ref + 3].copy()
        self._v_cmd = ws[_T.v_cmd : _T.v_cmd + 3].copy()
        self._f_measured = ws[_T.f_measured : _T.f_measured + 3].copy()
        self._path_point = ws[_T.path_point : _T.path_point + 3].tolist()
        fast = self._compiled
        self._hand_velocity = (
            fast.hand_velocity()
            if fast is not None
            else ws[_T.hand_velocity : _T.hand_velocity + 3].copy()
        )
        self.monitor.countdown = int(ws[_T.countdown])

    # ------------------------------------------------------------------ state
    @property
    def _fast(self) -> CompiledTick | None:
        """The compiled tick while it runs (not after a protective stop), else None."""
        return self._compiled if self.safety_stop is None else None

    @property
    def compiled(self) -> bool:
        """Whether the tick runs as compiled code (see the ``compiled`` argument)."""
        return self._compiled is not None

    @property
    def v_ref(self) -> np.ndarray:
        """The admittance's reference velocity after the last tick, shape (3,), m/s."""
        fast = self._fast
        return self._v_ref if fast is None else fast.vector(_T.v_ref)

    @property
    def v_cmd(self) -> np.ndarray:
        """The velocity command sent to the arm in the last tick, shape (3,), m/s."""
        fast = self._fast
        return self._v_cmd if fast is None else fast.vector(_T.v_cmd)

    @property
    def f_measured(self) -> np.ndarray:
        """The force sensor's reading in the last tick, shape (3,), N."""
        fast = self._fast
        return self._f_measured if fast is None else fast.vector(_T.f_measured)

    @property
    def hand_position(self) -> np.ndarray:
        """Hand (handle site) position, shape (3,), m."""
        return self.arm.hand_position()

    @property
    def hand_velocity(self) -> np.ndarray:
        """Hand (handle site) linear velocity after the last tick, shape (3,), m/s (read-only)."""
        fast = self._fast
        return self._hand_velocity if fast is None else fast.hand_velocity()

    @property
    def hand_speed(self) -> float:
        """Norm of :attr:`hand_velocity` (m/s)."""
        return self._hand_speed

    @property
    def cooperation(self) -> float:
        """Cooperation ``c`` in [0, 1]."""
        return float(self.coop.c)

    @property
    def motion_done(self) -> bool:
        """Whether the hand has come to rest after the last leg."""
        return self.t_motion_end is not None

    @property
    def stopped(self) -> bool:
        """Whether a protective stop has halted the arm (:attr:`safety_stop` says why)."""
        return self.safety_stop is not None

    @property
    def progress(self) -> float:
        """Arc-length progress ``d = s / L`` in [0, 1]."""
        return float(self.state.s / self.trajectory.length)

    def tangent(self) -> np.ndarray:
        """Unit direction of progress at the hand, shape (3,) (:meth:`Guide.tangent`)."""
        fast = self._fast
        if fast is not None:
            return fast.tangent()
        return self.guide.tangent(self.state, self.arm.hand_position())

    # ------------------------------------------------------------------ loop
    def _estimate(self) -> None:
        """``t_x`` and ``t_leg`` from the current state (:meth:`FastETC.times
        <langenv.control.motion_etc.FastETC.times>`)."""
        t_leg, rest = self.etc.times(self.state, self.arm.hand_position(), self._v_ref, self._v_cmd)
        self.t_x, self.t_leg = t_leg + rest, t_leg

    def reset(self) -> None:
        """Put the hand at rest at the trajectory's start; clear filters and timers."""
        self.arm.reset(self.trajectory.position(0.0))
        self.coop.reset()
        self.state = self.guide.initial_state()
        self._v_ref = np.zeros(3)
        self._v_cmd = np.zeros(3)
        self.f_user = np.zeros(3)
        self._f_measured = np.zeros(3)
        self.time = 0.0
        self.t_motion_end = None
        self._estimate()
        self.safety_stop = None
        self.monitor.reset()
        self._path_point = self.trajectory.position(self.state.s).tolist()
        self._measure_hand()
        if self._compiled is not None:
            self._compiled.load()

    def _measure_hand(self) -> None:
        v = self.arm.hand_velocity()
        v.flags.writeable = False
        self._hand_velocity = v
        self._hand_speed = vec.norm(v)
        self.path_deviation = math.dist(self.arm.hand_position().tolist(), self._path_point)

    def _offset(self, x: np.ndarray) -> tuple[float, float, float]:
        """``x - T(s)``: the hand's offset from its closest path point (m)."""
        x0, x1, x2 = x.tolist()
        p = self._path_point
        return (x0 - p[0], x1 - p[1], x2 - p[2])

    def tick(
        self,
        f_user: np.ndarray,
        p: float,
        p_dot: float,
        rng: np.random.Generator | None = None,
    ) -> None:
        """Advance one control tick.

        Args:
            f_user: Force the person applies at the handle, shape (3,), N.
            p: Physical pace during this tick.
            p_dot: Its time derivative (1/s).
            rng: Generator for the sensor noise (the env's ``np_random``).
        """
        if type(f_user) is not np.ndarray:
            f_user = np.asarray(f_user, dtype=np.float64)
        self.f_user = f_user
        if self.safety_stop is not None:  # protective stop: the arm holds still
            self._v_ref = np.zeros(3)
            self._v_cmd = np.zeros(3)
            self.arm.step(self._v_cmd, f_user)
            self._measure_hand()
            self.time += self.dt
            return
        if self._compiled is not None:
            self._compiled.tick(f_user, p, p_dot, rng)
            return
        self._tick_python(f_user, p, p_dot, rng)

    def _tick_python(
        self, f_user: np.ndarray, p: float, p_dot: float, rng: np.random.Generator | None
    ) -> None:
        """The tick in Python: the reference that the compiled tick repeats."""
        f_meas = self.sensor.measure(f_user, rng)
        self._f_measured = f_meas
        self.coop.update(vec.norm(f_meas), self.dt)
        x = self.arm.hand_position()
        if not self.state.done:
            self.guide.update(self.state, x)
            self._path_point = self.trajectory.position(self.state.s).tolist()
        offset = self._offset(x)
        braking = self.state.done
        if braking:
            self._v_ref = np.zeros(3)
        else:
            force = f_meas + self.guide.virtual_force(self.state, x, self._v_ref, p)
            v_ref = self.admittance.step(self._v_ref, force, p, p_dot, self.dt)
            self._v_ref = limit_velocity(v_ref, offset, self.limits)
        was_moving = bool(self._v_cmd.any())
        target = self._v_ref
        if not braking and vec.dot(f_meas, self.tangent()) > 0.0:  # pushed along: the governor
            target = cap_speed(target, self.guide.speed_limit(self.state, self._v_cmd))
        # the safety limits override the acceleration limit
        self._v_cmd = limit_velocity(follow(self._v_cmd, target, self._dv_max), offset, self.limits)
        self.arm.step(self._v_cmd, f_user)
        if braking:
            moving = bool(self._v_cmd.any())
            if not moving and self.t_motion_end is None:
                self.t_motion_end = self.time + (self.dt if was_moving else 0.0)
            self.t_x = vec.norm(self._v_cmd) / self.params.max_acceleration
            self.t_leg = self.t_x
        else:
            self._estimate()
        self._measure_hand()
        self.time += self.dt
        fault = self.arm.fault
        self.safety_stop = (
            fault
            if fault is not None
            else self.monitor.check(
                self.time,
                self._hand_speed,
                self.path_deviation,
                math.hypot(*f_user.tolist()),
                self.arm.joint_positions,
            )
        )
        if fault is None and self.safety_stop is not None and isinstance(self.arm, IOArm):
            self.arm.stop_for(self.safety_stop)  # speedStop now, in the period that found it
