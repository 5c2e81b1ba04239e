"""One 500 Hz tick of :class:`~langenv.motion.tick.GuidedArm`, compiled: :func:`control` before the
physics step, :func:`physics` (MuJoCo's own steps, by address) and :func:`observe` after it.

The tick's work array ``ws`` is :data:`TICK`, composed from the parts' own declarations (the
guide's, the admittance's, the command's, the sensor's, the cooperation filter's, the monitor's,
the safety layer's: each in the module of its Python reference) and the guided arm's
(:data:`MOTION_STATE`, :data:`MOTION_SETTINGS`); after ``TICK.size`` come the legs (rows of
:data:`~langenv.control.guide.LEG`) and the joints' bounds (two per joint). Each law is a
function beside its reference (:mod:`langenv.control.guide_kernels`,
:mod:`~langenv.control.admittance_kernels`, :mod:`~langenv.control.cooperation_kernels`,
:mod:`~langenv.control.command_kernels`, :mod:`~langenv.control.motion_etc_kernels`,
:mod:`langenv.robot.force_sensor_kernels`, :mod:`langenv.robot.arm_kernels`,
:mod:`langenv.robot.safety_kernels`); this module only reads and writes ``ws`` by :data:`TICK`'s
slots and calls them in the order of :meth:`GuidedArm._tick_python
<langenv.motion.tick.GuidedArm._tick_python>`, the reference, so the results are bit-identical
(``tests/test_compiled_tick.py``).
"""

from __future__ import annotations

import math

import numpy as np

from langenv.control import admittance_kernels as adm
from langenv.control import guide_kernels as guide
from langenv.control.admittance import ADMITTANCE_SETTINGS, ADMITTANCE_STATE
from langenv.control.command import COMMAND_SETTINGS, COMMAND_STATE
from langenv.control.command_kernels import cap_speed, follow
from langenv.control.cooperation import COOPERATION_SETTINGS, COOPERATION_STATE
from langenv.control.cooperation_kernels import update as cooperation_update
from langenv.control.guide import GUIDE_SETTINGS, GUIDE_STATE, LEG
from langenv.control.motion_etc_kernels import estimate_parts
from langenv.control.trajectory import SEGMENT
from langenv.control.trajectory_kernels import locate, point
from langenv.kernels import inline, kernel, mjc
from langenv.kernels.blas import mul_mat_vec
from langenv.kernels.pymath import dist3, hypot3
from langenv.kernels.views import Record, array_table, f8, f8_2, i8
from langenv.layout import Layout, field_table
from langenv.robot import arm_kernels
from langenv.robot.force_sensor import SENSOR_SETTINGS, SENSOR_STATE
from langenv.robot.force_sensor_kernels import deadband
from langenv.robot.safety import MONITOR_STATE, SAFETY_SETTINGS
from langenv.robot.safety_kernels import STOP_NONE, check, check_joints, limit_velocity

__all__ = [
    "BAD_FORCE",
    "MOTION_SETTINGS",
    "MOTION_STATE",
    "OK",
    "TICK",
    "TICK_ARRAYS",
    "control",
    "legs_at",
    "observe",
    "physics",
    "tick",
]

MOTION_STATE = field_table(
    """
    t_x               the motion ETC after the tick (s)
    time              time since the reset (s)
    t_end             when the motion ended (s; NaN while it goes on)
    path_point[3]     the closest path point T(s) (m)
    hand_velocity[3]  the hand's velocity after the tick (m/s)
    hand_speed        its norm (m/s)
    path_deviation    the hand's distance from T(s) (m)
    tangent[3]        the guide's direction of progress at the hand after the tick
    t_leg             the motion's time to the current leg's switch after the tick (s)
    """
)
"""The guided arm's own state (what :class:`~langenv.motion.tick.GuidedArm` exposes)."""
MOTION_SETTINGS = field_table(
    """
    dt  the tick (s)
    """
)
"""The guided arm's own settings."""

TICK = Layout(
    "tick",
    GUIDE_STATE,
    ADMITTANCE_STATE,
    COMMAND_STATE,
    SENSOR_STATE,
    COOPERATION_STATE,
    MOTION_STATE,
    MONITOR_STATE,
    GUIDE_SETTINGS,
    ADMITTANCE_SETTINGS,
    COMMAND_SETTINGS,
    SENSOR_SETTINGS,
    COOPERATION_SETTINGS,
    MOTION_SETTINGS,
    SAFETY_SETTINGS,
)
"""The tick's work array: state, then settings; then ``n_legs`` rows of
:data:`~langenv.control.guide.LEG` and two bounds per joint (:func:`legs_at`)."""

TICK_ARRAYS = Record(
    "tick_arrays",
    array_table(
        """
        ws         the tick's work array (:data:`TICK`, the legs, the bounds)
        path       the packed trajectory (rows of ``trajectory.SEGMENT``)
        aw         the arm controller's array (:data:`~langenv.robot.arm.ARM`)
        ai:int64   the arm's joint addresses
        jac        the handle's Jacobian (6 nv)
        xpos       the handle site's position
        xmat       the handle site's orientation
        qpos       ``mjData.qpos``
        qvel       ``mjData.qvel``
        ctrl       ``mjData.ctrl``
        qfrc       ``mjData.qfrc_applied``
        prm        FastETC's parameters
        tab        FastETC's tables
        ptr:int64  MuJoCo's pointers (:func:`langenv.kernels.mjc.pointers`)
        """
    ),
)
"""The tick's arrays, reached by address (:mod:`langenv.kernels.views`): what :func:`tick`,
:func:`control` and :func:`observe` take (a row of it, or of a record it begins:
:data:`langenv.env_kernels.SESSION`)."""

_T = TICK.at
_A = TICK_ARRAYS.at
_SEG = SEGMENT.size
_SIZE = TICK.size
_LEG = LEG.size
OK = 0
BAD_FORCE = -1
""":func:`control`'s answer for a non-finite force (nothing of the tick done); the admittance's
codes (:mod:`langenv.control.admittance_kernels`) for bad pace input; the arm's
``LIMITS_DUE`` when a joint is in its margin (Python re-solves, then ``arm_kernels.apply``)."""


@inline
def legs_at(ws: np.ndarray) -> np.ndarray:
    """The legs' rows in ``ws`` (flat)."""
    return ws[_SIZE : _SIZE + _LEG * int(ws[_T.n_legs])]


@inline
def _path(rec: np.ndarray) -> np.ndarray:
    return f8_2(rec, _A.path, _SEG)


@inline
def _bounds_at(ws: np.ndarray) -> np.ndarray:
    start = _SIZE + _LEG * int(ws[_T.n_legs])
    return ws[start : start + 2 * int(ws[_T.n_joints])]


@kernel
def _command(ws: np.ndarray, path: np.ndarray, x0: float, x1: float, x2: float) -> None:
    """The velocity command: ``v_ref`` (capped by the governor while pushed along) followed at
    the acceleration limit, within the safety limits."""
    o0, o1, o2 = x0 - ws[_T.path_point], x1 - ws[_T.path_point + 1], x2 - ws[_T.path_point + 2]
    c0, c1, c2 = ws[_T.v_cmd], ws[_T.v_cmd + 1], ws[_T.v_cmd + 2]
    ws[_T.was_moving] = 1.0 if (c0 != 0.0 or c1 != 0.0 or c2 != 0.0) else 0.0
    t0, t1, t2 = ws[_T.v_ref], ws[_T.v_ref + 1], ws[_T.v_ref + 2]
    if ws[_T.done] == 0.0:
        legs = legs_at(ws)
        s, leg = ws[_T.s], int(ws[_T.leg])
        b0, b1, b2 = guide.tangent(path, legs, s, leg, x0, x1, x2)
        f = _T.f_measured
        if ws[f] * b0 + ws[f + 1] * b1 + ws[f + 2] * b2 > 0.0:
            v_max = guide.speed_limit(path, legs, s, leg, ws[_T.acc], ws[_T.v_turn2], c0, c1, c2)
            t0, t1, t2 = cap_speed(t0, t1, t2, v_max)
    t0, t1, t2 = follow(c0, c1, c2, t0, t1, t2, ws[_T.dv_max])
    c0, c1, c2 = limit_velocity(t0, t1, t2, o0, o1, o2, ws[_T.hold], ws[_T.v_max])
    ws[_T.v_cmd], ws[_T.v_cmd + 1], ws[_T.v_cmd + 2] = c0, c1, c2


@kernel
def control(
    rec: np.ndarray,
    f0: float,
    f1: float,
    f2: float,
    m0: float,
    m1: float,
    m2: float,
    p: float,
    p_dot: float,
) -> int:
    """The tick up to the physics step: ``ctrl`` and ``qfrc_applied`` set.

    Args:
        rec: The tick's arrays (a row of :data:`TICK_ARRAYS`, or of a record it begins).
        f0, f1, f2: The person's force on the handle (N).
        m0, m1, m2: That force plus the sensor's noise (N); the deadband of
            :meth:`ForceSensor.measure <langenv.robot.force_sensor.ForceSensor.measure>` is
            applied here.
        p, p_dot: Physical pace and its rate.

    Returns:
        :data:`OK`; the arm's ``LIMITS_DUE`` (re-solve, then ``arm_kernels.apply``); or a
        negative code for bad input (nothing done for :data:`BAD_FORCE`).
    """
    ws, path, aw, ai = f8(rec, _A.ws), _path(rec), f8(rec, _A.aw), i8(rec, _A.ai)
    jac, xpos, xmat = f8(rec, _A.jac), f8(rec, _A.xpos), f8(rec, _A.xmat)
    qpos, qvel, ctrl, qfrc = f8(rec, _A.qpos), f8(rec, _A.qvel), f8(rec, _A.ctrl), f8(rec, _A.qfrc)
    ok, m0, m1, m2 = deadband(m0, m1, m2, ws[_T.deadband])
    if not ok:
        return BAD_FORCE
    ws[_T.f_measured], ws[_T.f_measured + 1], ws[_T.f_measured + 2] = m0, m1, m2
    r, c = cooperation_update(ws[_T.r], m0, m1, m2, ws[_T.keep], ws[_T.inv_f_max])
    ws[_T.r] = r
    ws[_T.c] = c
    x0, x1, x2 = xpos[0], xpos[1], xpos[2]
    if ws[_T.done] == 0.0:
        s, leg, done = guide.update(
            path, legs_at(ws), ws[_T.s], int(ws[_T.leg]), int(ws[_T.n_legs]), ws[_T.tol2],
            x0, x1, x2,
        )  # fmt: skip
        ws[_T.s], ws[_T.leg] = s, leg
        if done:
            ws[_T.done] = 1.0
        i, t = locate(path, s, False)
        ws[_T.path_point], ws[_T.path_point + 1], ws[_T.path_point + 2] = point(path, i, t)
    v = _T.v_ref
    if ws[_T.done] != 0.0:
        ws[v], ws[v + 1], ws[v + 2] = 0.0, 0.0, 0.0
    else:
        g0, g1, g2 = guide.virtual_force(
            path, legs_at(ws), ws[_T.s], int(ws[_T.leg]), ws[_T.k], ws[_T.f_prop],
            ws[_T.ff_mass], x0, x1, x2, ws[v], ws[v + 1], ws[v + 2], p,
        )  # fmt: skip
        code, v0, v1, v2 = adm.step(
            ws[v], ws[v + 1], ws[v + 2], m0 + g0, m1 + g1, m2 + g2, p, p_dot, ws[_T.dt],
            ws[_T.d_over_m], ws[_T.inv_d],
        )  # fmt: skip
        if code != OK:
            return code
        pp = _T.path_point
        o0, o1, o2 = x0 - ws[pp], x1 - ws[pp + 1], x2 - ws[pp + 2]
        v0, v1, v2 = limit_velocity(v0, v1, v2, o0, o1, o2, ws[_T.hold], ws[_T.v_max])
        ws[v], ws[v + 1], ws[v + 2] = v0, v1, v2
    _command(ws, path, x0, x1, x2)
    c0, c1, c2 = ws[_T.v_cmd], ws[_T.v_cmd + 1], ws[_T.v_cmd + 2]
    code = arm_kernels.solve(aw, ai, jac, xpos, xmat, qpos, qvel, c0, c1, c2)
    if code != OK:
        return code
    arm_kernels.apply(aw, ai, jac, ctrl, qfrc, f0, f1, f2)
    return OK


@kernel
def observe(rec: np.ndarray, force: float) -> int:
    """The tick after the physics step: ``t_x``, the hand's velocity and distance from the
    path, the time, and the safety monitor (``rec``: as :func:`control`'s; ``force``: the
    magnitude on the handle, N).

    Returns:
        The limit breached (:mod:`langenv.robot.safety_kernels`' ``STOP_*``), ``STOP_NONE`` if none.
    """
    ws, path, prm, tab = f8(rec, _A.ws), _path(rec), f8(rec, _A.prm), f8(rec, _A.tab)
    ai, jac, xpos = i8(rec, _A.ai), f8(rec, _A.jac), f8(rec, _A.xpos)
    qpos, qvel = f8(rec, _A.qpos), f8(rec, _A.qvel)
    c0, c1, c2 = ws[_T.v_cmd], ws[_T.v_cmd + 1], ws[_T.v_cmd + 2]
    tan = _T.tangent
    if ws[_T.done] != 0.0:
        moving = c0 != 0.0 or c1 != 0.0 or c2 != 0.0
        if not moving and math.isnan(ws[_T.t_end]):
            ws[_T.t_end] = ws[_T.time] + (ws[_T.dt] if ws[_T.was_moving] != 0.0 else 0.0)
        ws[_T.t_x] = math.sqrt(c0 * c0 + c1 * c1 + c2 * c2) / ws[_T.max_acc]
        ws[_T.t_leg] = ws[_T.t_x]
        e = _T.end_tangent
        ws[tan], ws[tan + 1], ws[tan + 2] = ws[e], ws[e + 1], ws[e + 2]
    else:
        v = _T.v_ref
        t_leg, rest = estimate_parts(
            prm,
            tab,
            path,
            int(ws[_T.leg]),
            ws[_T.s],
            False,
            (xpos[0], xpos[1], xpos[2]),
            (ws[v], ws[v + 1], ws[v + 2]),
            (c0, c1, c2),
        )
        ws[_T.t_x] = t_leg + rest
        ws[_T.t_leg] = t_leg
        b0, b1, b2 = guide.tangent(
            path, legs_at(ws), ws[_T.s], int(ws[_T.leg]), xpos[0], xpos[1], xpos[2]
        )
        ws[tan], ws[tan + 1], ws[tan + 2] = b0, b1, b2
    nv = qvel.shape[0]
    hv = ws[_T.hand_velocity : _T.hand_velocity + 3]  # J_p qvel, as mju_mulMatVec (not BLAS)
    mul_mat_vec(hv, jac, qvel, 3, nv)
    speed = math.sqrt(hv[0] * hv[0] + hv[1] * hv[1] + hv[2] * hv[2])
    ws[_T.hand_speed] = speed
    pp = _T.path_point
    dev = dist3(xpos[0], xpos[1], xpos[2], ws[pp], ws[pp + 1], ws[pp + 2])
    ws[_T.path_deviation] = dev
    ws[_T.time] += ws[_T.dt]
    stop = check(force, dev, speed, ws[_T.f_max], ws[_T.d_max], ws[_T.v_trip])
    if stop != STOP_NONE:
        return stop
    if ws[_T.has_joint_limits] != 0.0:
        ws[_T.countdown] -= 1.0
        if ws[_T.countdown] <= 0.0:
            stop, due = check_joints(
                qpos, ai, _bounds_at(ws), int(ws[_T.n_joints]), ws[_T.per_tick]
            )
            if stop != STOP_NONE:
                return stop
            ws[_T.countdown] = due
    return STOP_NONE


@kernel
def physics(ptr: np.ndarray) -> None:
    """MuJoCo's ``mj_step2``, ``mj_step1`` and the handle's ``mj_jacSite`` (``ptr``:
    :func:`langenv.kernels.mjc.pointers`), as ``GuidedArm`` calls them through the bindings."""
    m, d = ptr[mjc.P_MODEL], ptr[mjc.P_DATA]
    mjc.call_md(ptr[mjc.P_STEP2], m, d)
    mjc.call_md(ptr[mjc.P_STEP1], m, d)
    mjc.call_jac(ptr[mjc.P_JACSITE], m, d, ptr[mjc.P_JACP], ptr[mjc.P_JACR], ptr[mjc.P_SITE])


@kernel
def tick(
    rec: np.ndarray,
    f0: float,
    f1: float,
    f2: float,
    m0: float,
    m1: float,
    m2: float,
    p: float,
    p_dot: float,
) -> tuple[int, int]:
    """A whole tick in one call: :func:`control`, :func:`physics`, :func:`observe` (``rec``: as
    :func:`control`'s).

    Returns:
        ``(control's answer, observe's answer)``; when control's is not :data:`OK` the tick
        stopped there (physics not stepped; observe's answer is ``STOP_NONE``) and the caller
        finishes it (:meth:`CompiledTick.finish
        <langenv.motion.compiled_tick.CompiledTick.finish>`).
    """
    code = control(rec, f0, f1, f2, m0, m1, m2, p, p_dot)
    if code != OK:
        return code, STOP_NONE
    physics(i8(rec, _A.ptr))
    return OK, observe(rec, hypot3(f0, f1, f2))
