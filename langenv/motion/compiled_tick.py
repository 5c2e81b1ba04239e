"""The compiled tick bound to one :class:`~langenv.motion.tick.GuidedArm`: its arrays, packed from
the parts' declarations, and the calls.

:class:`CompiledTick` packs the guided arm's work array (:data:`~langenv.motion.tick_kernels.TICK`:
each part's settings by the names it declares, :meth:`GuidedArm.tick_settings
<langenv.motion.tick.GuidedArm.tick_settings>`; then the legs and the joints' bounds) and the arm
controller's (:meth:`Arm.compiled_arrays <langenv.robot.arm.Arm.compiled_arrays>`), runs a tick
as one compiled call (:func:`langenv.motion.tick_kernels.tick`: the control law, MuJoCo's
``mj_step2``/``mj_step1``/``mj_jacSite`` through :mod:`langenv.kernels.mjc`, the observation),
and lets the guided arm take back the state its Python objects expose after each tick
(:meth:`GuidedArm.take_tick_state <langenv.motion.tick.GuidedArm.take_tick_state>`). Rare paths
(joint-limit avoidance, protective stops, bad input) are handed to the Python parts, which stay
the reference.
"""

from __future__ import annotations

import math
from typing import Any

import mujoco
import numpy as np

from langenv.control.guide import LEG
from langenv.errors import ActionError, ConfigError
from langenv.kernels import mjc
from langenv.motion import tick_kernels as mk
from langenv.robot import arm_kernels as ak
from langenv.robot.safety_kernels import STOP_NONE

__all__ = ["CompiledTick"]

_T = mk.TICK.at


class CompiledTick:
    """The compiled 500 Hz tick of ``motion`` (built once; :meth:`load` after each reset).

    Args:
        motion: The :class:`~langenv.motion.tick.GuidedArm` whose parts the tick repeats (typed
            ``Any``: ``langenv.motion.tick`` imports this module, and the import graph has no
            cycles).

    Attributes:
        ws: The tick's work array (:data:`~langenv.motion.tick_kernels.TICK`, the legs, the bounds).
        aw, ai: The arm controller's arrays (:mod:`langenv.robot.arm_kernels`).
    """

    def __init__(self, motion: Any) -> None:
        self.motion = motion
        arm, guide, monitor = motion.arm, motion.guide, motion.monitor
        legs = guide.leg_rows().reshape(-1)
        bounds = monitor.bounds()
        ws = mk.TICK.zeros(extra=legs.size + bounds.size)
        mk.TICK.pack_all(ws, motion.tick_state(), motion.tick_settings())
        ws[mk.TICK.size : mk.TICK.size + legs.size] = legs
        ws[mk.TICK.size + legs.size :] = bounds
        assert legs.size == LEG.size * guide.n_legs
        self.ws = ws
        self.path, self.prm, self.tab = motion.etc.path, motion.etc.prm, motion.etc.tab
        self.aw, self.ai = arm.compiled_arrays()
        views = arm.compiled_views()
        self.jac, self.xpos, self.xmat = views["jac"], views["xpos"], views["xmat"]
        self.qpos, self.qvel, self.ctrl, self.qfrc = (
            views["qpos"], views["qvel"], views["ctrl"], views["qfrc"],
        )  # fmt: skip
        self.model, self.data = arm.model, arm.data
        self.full_dofs: bool = arm.full_dofs
        self.ptr = mjc.pointers(arm.model, arm.data, views["jacp"], views["jacr"], arm.site_id)
        self._hv: np.ndarray | None = None
        self._arrays: tuple[np.ndarray, ...] = (
            self.ws, self.path, self.aw, self.ai, self.jac, self.xpos, self.xmat, self.qpos,
            self.qvel, self.ctrl, self.qfrc, self.prm, self.tab, self.ptr,
        )  # fmt: skip

    def arrays(self) -> tuple[np.ndarray, ...]:
        """The arrays :func:`~langenv.motion.tick_kernels.tick` takes first, in its order (``ws``
        ... ``ptr``)."""
        return self._arrays

    # ------------------------------------------------------------------ state
    def load(self) -> None:
        """Copy the Python parts' state (after a reset) into the work arrays."""
        m = self.motion
        mk.TICK.pack(self.ws, m.tick_state())
        self._hv = None
        m.arm.load_compiled_state(self.aw)

    def store(self) -> None:
        """Copy the work arrays' state into the Python parts (before a Python tick)."""
        self.motion.store_tick_state(self.ws)
        self.motion.arm.store_compiled_state(self.aw)

    def sync(self) -> None:
        """Let the guided arm take the state its Python objects expose (after compiled ticks)."""
        self.motion.take_tick_state(self.ws)
        self._hv = None

    def vector(self, slot: int) -> np.ndarray:
        """Three state entries from ``slot`` on, as a new array."""
        return self.ws[slot : slot + 3].copy()

    # ------------------------------------------------------------------ the tick
    def tick(
        self, f_user: np.ndarray, p: float, p_dot: float, rng: np.random.Generator | None
    ) -> None:
        """One tick of ``motion`` (not stopped); the same operations as ``GuidedArm`` in Python."""
        m = self.motion
        if f_user.shape != (3,) or f_user.dtype != np.float64:
            f_user = np.asarray(f_user, np.float64)
            if f_user.shape != (3,):
                m.sensor.measure(f_user, None)  # raises its ActionError
        f0, f1, f2 = f_user.tolist()
        std = m.sensor.noise_std
        if rng is not None and std > 0.0:  # ForceSensor.measure's noise, drawn the same way
            n0, n1, n2 = rng.normal(0.0, std, 3).tolist()
            m0, m1, m2 = f0 + n0, f1 + n1, f2 + n2
        else:
            m0, m1, m2 = f0, f1, f2
        args: tuple[Any, ...] = (*self.arrays(), f0, f1, f2, m0, m1, m2, p, p_dot)
        code, stop = mk.tick(*args)
        if code != mk.OK:
            self.finish_rare(code, f_user, p, p_dot)
            self.finish(f0, f1, f2)
            return
        if not self.full_dofs:
            m.arm.update_jacobian()
        self.sync()
        if stop != STOP_NONE:
            self.stop(f0, f1, f2)

    def finish(self, f0: float, f1: float, f2: float) -> None:
        """The rest of a tick whose control part ended in :meth:`finish_rare`: the physics step,
        ``observe``, the Python-visible state and the safety stop."""
        mujoco.mj_step2(self.model, self.data)
        mujoco.mj_step1(self.model, self.data)
        self.motion.arm.update_jacobian()
        stop = mk.observe(
            self.ws, self.path, self.prm, self.tab, self.ai, self.jac, self.xpos, self.qpos,
            self.qvel, math.hypot(f0, f1, f2),
        )  # fmt: skip
        self.sync()
        if stop != STOP_NONE:
            self.stop(f0, f1, f2)

    def finish_rare(self, code: int, f_user: np.ndarray, p: float, p_dot: float) -> None:
        """The control part answered ``code``: bad input (the Python part raises its error) or
        joint-limit avoidance (Python re-solves, then the compiled ``apply``)."""
        arm = self.motion.arm
        if code == mk.BAD_FORCE:
            raise ActionError(f"f must be finite, got {f_user.tolist()}")
        if code != ak.LIMITS_DUE:
            self.motion.admittance.step(np.zeros(3), np.zeros(3), p, p_dot, self.motion.dt)
            raise ConfigError(
                f"GuidedArm.tick: the admittance rejected the force or velocity (p={p!r}, "
                f"p_dot={p_dot!r})"
            )
        arm.avoid_limits_compiled(self.aw)
        f0, f1, f2 = f_user.tolist()
        ak.apply(self.aw, self.ai, self.jac, self.ctrl, self.qfrc, f0, f1, f2)

    def stop(self, f0: float, f1: float, f2: float) -> None:
        """A limit was breached: the monitor names the stop (the same checks, in Python)."""
        m = self.motion
        m.monitor.countdown = 1
        stop = m.monitor.check(
            m.time, m.hand_speed, m.path_deviation, math.hypot(f0, f1, f2), m.arm.joint_positions
        )
        if stop is None:  # cannot happen: the kernel and the monitor test the same numbers
            raise RuntimeError("the compiled safety check and SafetyMonitor disagree")
        m.safety_stop = stop
        self.store()

    def tangent(self) -> np.ndarray:
        """The guide's direction at the hand (``Guide.tangent(state, x)``), shape (3,)."""
        return self.ws[_T.tangent : _T.tangent + 3].copy()

    def hand_velocity(self) -> np.ndarray:
        """The hand's velocity after the last tick, shape (3,), m/s (read-only; one array per
        tick, as the Python tick keeps)."""
        v = self._hv
        if v is None:
            v = self._hv = self.ws[_T.hand_velocity : _T.hand_velocity + 3].copy()
            v.flags.writeable = False
        return v
