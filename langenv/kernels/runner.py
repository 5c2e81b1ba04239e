"""The compiled tick bound to one :class:`~langenv.motion.GuidedArm`: packing and syncing.

:class:`CompiledTick` packs the settings of the guided arm's parts (guide, admittance,
cooperation filter, safety limits, arm controller, FastETC) into the float64 work arrays of
:mod:`langenv.kernels.tick` and :mod:`langenv.kernels.arm`, runs a tick as one compiled call
(:func:`langenv.kernels.tick.tick`: the control law, MuJoCo's ``mj_step2``/``mj_step1``/
``mj_jacSite`` through :mod:`langenv.kernels.mjc`, the observation), and writes the state that
the Python objects expose (guide state, cooperation, ``t_x``, time, ...) back after each tick
(:meth:`CompiledTick.sync`). Rare paths (joint-limit avoidance, protective stops, bad input) are
handed to the Python parts, which stay the reference.
"""

from __future__ import annotations

import math
from typing import Any

import mujoco
import numpy as np

from langenv.control.guide import GuideState
from langenv.errors import ActionError, ConfigError
from langenv.kernels import arm as ak
from langenv.kernels import mjc
from langenv.kernels import tick as tk
from langenv.kernels.path import pack as pack_path

__all__ = ["CompiledTick"]


class CompiledTick:
    """The compiled 500 Hz tick of ``motion`` (built once; :meth:`load` after each reset).

    Args:
        motion: The :class:`~langenv.motion.GuidedArm` whose parts the tick repeats (typed
            ``Any``: ``langenv.motion`` imports this module, and the import graph has no cycles).
    """

    def __init__(self, motion: Any) -> None:
        self.motion = motion
        arm, guide, coop = motion.arm, motion.guide, motion.coop
        n, nv, k = arm.n_joints, arm.model.nv, arm._task
        self.path = pack_path(motion.trajectory)
        self.prm, self.tab = motion.etc.prm, motion.etc.tab
        n_legs = guide._n_legs
        ws = np.zeros(tk.LEGS + tk.LEG_COLS * n_legs + 2 * n)
        ws[tk.C_END_TAN : tk.C_END_TAN + 3] = guide.tangent(
            GuideState(guide._ends[-1], n_legs, True)
        )
        ws[tk.C_INV_FMAX] = coop._inv_f_max
        ws[tk.C_DEADBAND] = motion.sensor.deadband
        ws[tk.C_DT] = motion.dt
        ws[tk.C_KEEP] = (
            coop._keep if coop._dt == motion.dt else math.exp(coop._log_alpha * motion.dt)
        )
        ws[tk.C_K], ws[tk.C_FPROP], ws[tk.C_TOL2] = guide._k, guide._f_prop, guide._tol2
        ws[tk.C_FFMASS], ws[tk.C_ACC], ws[tk.C_VTURN2] = guide._ff_mass, guide._acc, guide._v_turn2
        adm = motion.admittance
        ws[tk.C_DOVERM], ws[tk.C_INVD] = adm._d_over_m, adm._inv_d
        ws[tk.C_MAXACC] = motion.params.max_acceleration
        ws[tk.C_DVMAX] = motion._dv_max
        lim, mon = motion.limits, motion.monitor
        ws[tk.C_HOLD], ws[tk.C_VMAX] = lim.hold_deviation, lim.max_speed
        ws[tk.C_FMAX], ws[tk.C_DMAX], ws[tk.C_VTRIP] = mon._f_max, mon._d_max, mon._v_trip
        ws[tk.C_PERTICK], ws[tk.C_HASJL] = mon._per_tick, float(mon._has_joint_limits)
        ws[tk.C_NLEGS], ws[tk.C_NJ] = n_legs, n
        for j in range(n_legs):
            row = tk.LEGS + tk.LEG_COLS * j
            ws[row : row + tk.LEG_COLS] = (
                guide._starts[j],
                guide._ends[j],
                *guide._end_pts[j],
                guide._end_angle[j],
                guide._q_sw[j],
                guide._gate[j],
            )
        bounds = tk.LEGS + tk.LEG_COLS * n_legs
        ws[bounds:] = np.asarray(mon._bounds, dtype=np.float64).reshape(-1)
        self.ws = ws

        aw = np.zeros(ak.J0 + 6 * n + k * n)
        aw[ak.A_VMAX], aw[ak.A_KP] = arm.max_hand_speed, arm._kp
        aw[ak.A_EMAX], aw[ak.A_EMAX2], aw[ak.A_LAMBDA2] = arm._emax, arm._emax2, arm._lambda2
        aw[ak.A_DT], aw[ak.A_TASK], aw[ak.A_N], aw[ak.A_NV] = arm.dt, k, n, nv
        aw[ak.A_HASLIM], aw[ak.A_FULL] = float(arm._has_limits), float(arm._full_dofs)
        aw[ak.A_MAXQD] = float(np.max(1.0 / arm._inv_qdmax))
        for b, values in enumerate((arm._inv_qdmax, arm._lo, arm._hi, arm._lo_m, arm._hi_m)):
            aw[ak.J0 + b * n : ak.J0 + (b + 1) * n] = values
        self.aw = aw
        # the arm's reference point lives in aw: Arm's in-place updates (reset, Python step)
        # and the kernel's then act on the same three numbers
        aw[ak.A_XREF : ak.A_XREF + 3] = arm._x_ref
        arm._x_ref = aw[ak.A_XREF : ak.A_XREF + 3]
        self.ai = np.concatenate([arm._dofs, arm._qadr, arm._act_ids]).astype(np.int64)
        self.jac = arm._jac.reshape(-1)
        d = arm.data
        self.xpos, self.xmat = arm._site_xpos, arm._site_xmat
        self.qpos, self.qvel, self.ctrl, self.qfrc = d.qpos, d.qvel, d.ctrl, d.qfrc_applied
        self.model, self.data = arm.model, d
        self._full_dofs: bool = arm._full_dofs
        self.ptr = mjc.pointers(arm.model, d, arm._jacp, arm._jacr, arm.site_id)
        self._hv: np.ndarray | None = None

    # ------------------------------------------------------------------ state
    def load(self) -> None:
        """Copy the Python parts' state (after a reset) into the work arrays."""
        m, ws, aw, arm = self.motion, self.ws, self.aw, self.motion.arm
        st = m.state
        ws[tk.S_S], ws[tk.S_LEG], ws[tk.S_DONE] = st.s, st.leg, float(st.done)
        ws[tk.S_VREF : tk.S_VREF + 3] = m._v_ref
        ws[tk.S_VCMD : tk.S_VCMD + 3] = m._v_cmd
        ws[tk.S_FMEAS : tk.S_FMEAS + 3] = m._f_measured
        ws[tk.S_R], ws[tk.S_C] = m.coop.r, m.coop.c
        ws[tk.S_TX], ws[tk.S_TIME] = m.t_x, m.time
        ws[tk.S_TEND] = math.nan if m.t_motion_end is None else m.t_motion_end
        ws[tk.S_PP : tk.S_PP + 3] = m._path_point
        ws[tk.S_HV : tk.S_HV + 3] = m._hand_velocity
        ws[tk.S_HS], ws[tk.S_DEV] = m._hand_speed, m.path_deviation
        ws[tk.S_MONCD] = m.monitor._countdown
        self._hv = None
        ws[tk.S_TAN : tk.S_TAN + 3] = m.guide.tangent(st, arm._site_xpos.copy())
        aw[ak.A_COUNTDOWN] = arm._limit_countdown
        aw[ak.A_ROTB : ak.A_ROTB + 27] = arm._rot_b.reshape(-1)

    def store(self) -> None:
        """Copy the work arrays' state into the Python parts (before a Python tick)."""
        m, ws = self.motion, self.ws
        m._v_ref = ws[tk.S_VREF : tk.S_VREF + 3].copy()
        m._v_cmd = ws[tk.S_VCMD : tk.S_VCMD + 3].copy()
        m._f_measured = ws[tk.S_FMEAS : tk.S_FMEAS + 3].copy()
        m._path_point = ws[tk.S_PP : tk.S_PP + 3].tolist()
        m._hand_velocity = self.hand_velocity()
        m.monitor._countdown = int(ws[tk.S_MONCD])
        m.arm._limit_countdown = int(self.aw[ak.A_COUNTDOWN])

    def vector(self, slot: int) -> np.ndarray:
        """Three state entries from ``slot`` on, as a new array."""
        return self.ws[slot : slot + 3].copy()

    # ------------------------------------------------------------------ the tick
    def tick(
        self, f_user: np.ndarray, p: float, p_dot: float, rng: np.random.Generator | None
    ) -> None:
        """One tick of ``motion`` (not stopped); the same operations as ``GuidedArm`` in Python."""
        m, ws, arm = self.motion, self.ws, self.motion.arm
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
        code, stop = tk.tick(
            ws, self.path, self.aw, self.ai, self.jac, self.xpos, self.xmat, self.qpos,
            self.qvel, self.ctrl, self.qfrc, self.prm, self.tab, self.ptr,
            f0, f1, f2, m0, m1, m2, p, p_dot,
        )  # fmt: skip
        if code != tk.OK:
            self._rare(code, f_user, p, p_dot)
            self.finish(f0, f1, f2)
            return
        if not self._full_dofs:
            arm._update_jacobian()
        self.sync()
        if stop != tk.STOP_NONE:
            self._stop(f0, f1, f2)

    def finish(self, f0: float, f1: float, f2: float) -> None:
        """The rest of a tick whose control part ended in :meth:`_rare`: the physics step,
        ``observe``, the Python-visible state and the safety stop."""
        ws, arm = self.ws, self.motion.arm
        mujoco.mj_step2(self.model, self.data)
        mujoco.mj_step1(self.model, self.data)
        arm._update_jacobian()
        stop = tk.observe(
            ws, self.path, self.prm, self.tab, self.ai, self.jac, self.xpos, self.qpos, self.qvel,
            math.hypot(f0, f1, f2),
        )  # fmt: skip
        self.sync()
        if stop != tk.STOP_NONE:
            self._stop(f0, f1, f2)

    def sync(self) -> None:
        """Write the work arrays' state that the Python objects expose (after compiled ticks)."""
        m, ws = self.motion, self.ws
        s, leg, done = ws[: tk.S_VREF].tolist()
        st = m.state
        st.s, st.leg, st.done = s, int(leg), done != 0.0
        r, c, t_x, time, t_end = ws[tk.S_R : tk.S_PP].tolist()
        m.coop.r, m.coop.c = r, c
        m.t_x, m.time = t_x, time
        if t_end == t_end:  # not NaN
            m.t_motion_end = t_end
        m._hand_speed, m.path_deviation = ws[tk.S_HS : tk.S_MONCD].tolist()
        self._hv = None

    def _rare(self, code: int, f_user: np.ndarray, p: float, p_dot: float) -> None:
        """Bad input (the Python part raises its error) or joint-limit avoidance."""
        arm, aw = self.motion.arm, self.aw
        if code == tk.BAD_FORCE:
            raise ActionError(f"f must be finite, got {f_user.tolist()}")
        if code != ak.LIMITS_DUE:
            self.motion.admittance.step(np.zeros(3), np.zeros(3), p, p_dot, self.motion.dt)
            raise ConfigError(
                f"GuidedArm.tick: the admittance rejected the force or velocity (p={p!r}, "
                f"p_dot={p_dot!r})"
            )
        n, k = arm.n_joints, arm._task
        qdot = aw[ak.J0 + 5 * n : ak.J0 + 6 * n]
        arm._qdot[:] = qdot
        arm._xdot[:] = aw[ak.A_XDOT : ak.A_XDOT + k]
        q = arm._qpos_view if arm._qpos_view is not None else self.data.qpos[arm._qadr]
        arm._avoid_limits(q)
        qdot[:] = arm._qdot
        f0, f1, f2 = f_user.tolist()
        ak.apply(aw, self.ai, self.jac, self.ctrl, self.qfrc, f0, f1, f2)

    def _stop(self, f0: float, f1: float, f2: float) -> None:
        """A limit was breached: the monitor names the stop (the same checks, in Python)."""
        m = self.motion
        m.monitor._countdown = 1
        stop = m.monitor.check(
            m.time, m._hand_speed, m.path_deviation, math.hypot(f0, f1, f2), m.arm.joint_positions
        )
        if stop is None:  # cannot happen: the kernel and the monitor test the same numbers
            raise RuntimeError("the compiled safety check and SafetyMonitor disagree")
        m.safety_stop = stop
        self.store()

    def tangent(self) -> np.ndarray:
        """The guide's direction at the hand (``Guide.tangent(state, x)``), shape (3,)."""
        return self.ws[tk.S_TAN : tk.S_TAN + 3].copy()

    def hand_velocity(self) -> np.ndarray:
        """The hand's velocity after the last tick, shape (3,), m/s (read-only; one array per
        tick, as the Python tick keeps)."""
        v = self._hv
        if v is None:
            v = self._hv = self.ws[tk.S_HV : tk.S_HV + 3].copy()
            v.flags.writeable = False
        return v
