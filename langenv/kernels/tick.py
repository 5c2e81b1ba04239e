"""One 500 Hz tick of :class:`~langenv.motion.GuidedArm`, compiled: :func:`control` before the
physics step and :func:`observe` after it.

``ws`` holds the tick's state and settings (float64; the ``S_*`` slots are state, the ``C_*``
slots settings, then per leg :data:`LEG_COLS` entries from :data:`LEGS` and per joint the
monitor's bounds). The operations repeat those of the Python parts, in their order:
:meth:`ForceSensor.measure <langenv.robot.force_sensor.ForceSensor.measure>`,
:meth:`CooperationFilter.update <langenv.control.cooperation.CooperationFilter.update>`,
:class:`~langenv.control.guide.Guide` (``update``, ``virtual_force``, ``tangent``,
``speed_limit``), :meth:`VariableAdmittance.step
<langenv.control.admittance.VariableAdmittance.step>`,
:func:`~langenv.safety.limit_velocity`, :func:`~langenv.control.command.follow` and
:func:`~langenv.control.command.cap_speed`, the arm's controller (:mod:`langenv.kernels.arm`),
:class:`~langenv.control.motion_etc.FastETC` and :class:`~langenv.safety.SafetyMonitor`.
"""

from __future__ import annotations

import math

import numpy as np

from langenv.control.guide import _TURNED_COS2, GOVERNOR_SHARE
from langenv.kernels import arm as arm_kernel
from langenv.kernels import inline, kernel, mjc
from langenv.kernels.blas import mul_mat_vec
from langenv.kernels.etc import estimate
from langenv.kernels.path import RADIUS, closest, frame, locate, point, tool_angle, unit_tangent
from langenv.kernels.pymath import dist3, hypot3
from langenv.safety import HOLD_TIME, JOINT_CHECK_MAX

__all__ = ["control", "observe", "physics", "tick"]

# state
S_S, S_LEG, S_DONE, S_VREF, S_VCMD, S_FMEAS = 0, 1, 2, 3, 6, 9
S_R, S_C, S_TX, S_TIME, S_TEND, S_PP, S_HV, S_HS, S_DEV, S_MONCD, S_WAS, S_TAN = (
    12,
    13,
    14,
    15,
    16,
    17,
    20,
    23,
    24,
    25,
    26,
    27,
)
N_STATE = 30
"""State slots (``S_TAN``: the guide's tangent at the hand after the tick, 3)."""
# settings
C_END_TAN, C_DEADBAND, C_KEEP, C_INV_FMAX, C_DT, C_K, C_FPROP, C_TOL2, C_FFMASS, C_ACC = (
    30,
    33,
    34,
    35,
    36,
    37,
    38,
    39,
    40,
    41,
)
C_VTURN2 = 55
C_DOVERM, C_INVD, C_MAXACC, C_DVMAX, C_HOLD, C_VMAX, C_FMAX, C_DMAX, C_VTRIP = (
    42,
    43,
    44,
    45,
    46,
    47,
    48,
    49,
    50,
)
C_PERTICK, C_HASJL, C_NLEGS, C_NJ = 51, 52, 53, 54
LEGS = 56
"""Start of the legs: start, end, end point (3), end tool angle, switch distance, gate."""
LEG_COLS = 8

# control()'s answers (the arm's LIMITS_DUE is 1)
OK = 0
BAD_FORCE, BAD_PACE, BAD_PACE_RATE, BAD_PACE_END, BAD_TOTAL_FORCE, BAD_VELOCITY = (
    -1,
    -2,
    -3,
    -4,
    -5,
    -6,
)
# observe()'s answers: the limit breached
STOP_NONE, STOP_FORCE, STOP_DEVIATION, STOP_SPEED, STOP_JOINT = 0, 1, 2, 3, 4


@inline
def _leg(ws: np.ndarray, k: int, col: int) -> float:
    return ws[LEGS + LEG_COLS * k + col]


@kernel
def _limit_velocity(
    ws: np.ndarray, v0: float, v1: float, v2: float, o0: float, o1: float, o2: float
) -> tuple[float, float, float]:
    """:func:`~langenv.safety.limit_velocity` (``changed`` or not, the values are the same)."""
    vmax = ws[C_VMAX]
    hold = ws[C_HOLD]
    d2 = o0 * o0 + o1 * o1 + o2 * o2
    free = hold - vmax * HOLD_TIME
    if not (free > 0.0 and d2 <= free * free):
        d = math.sqrt(d2)
        out = (v0 * o0 + v1 * o1 + v2 * o2) / d if d > 0.0 else 0.0
        cap = (hold - d) / HOLD_TIME
        cap = 0.0 if 0.0 > cap else cap
        if out > cap:
            k = (out - cap) / d
            v0, v1, v2 = v0 - k * o0, v1 - k * o1, v2 - k * o2
    s2 = v0 * v0 + v1 * v1 + v2 * v2
    if s2 > vmax * vmax:
        k = vmax / math.sqrt(s2)
        v0, v1, v2 = v0 * k, v1 * k, v2 * k
    return v0, v1, v2


@kernel
def _guide_update(ws: np.ndarray, path: np.ndarray, x0: float, x1: float, x2: float) -> None:
    """``Guide.update``: closest point in the leg, next leg (or done) near its end pose once
    the closest point has reached the leg's gate."""
    k = int(ws[S_LEG])
    s_end = _leg(ws, k, 1)
    s = closest(path, x0, x1, x2, ws[S_S], _leg(ws, k, 0), s_end)
    ws[S_S] = s
    d0, d1, d2 = x0 - _leg(ws, k, 2), x1 - _leg(ws, k, 3), x2 - _leg(ws, k, 4)
    dphi = _leg(ws, k, 5) - tool_angle(path, s)
    if d0 * d0 + d1 * d1 + d2 * d2 + dphi * dphi < ws[C_TOL2] and s >= _leg(ws, k, 7):
        ws[S_LEG] = k + 1
        if k + 1 >= int(ws[C_NLEGS]):
            ws[S_DONE] = 1.0
            ws[S_S] = s_end


@kernel
def _virtual_force(
    ws: np.ndarray, path: np.ndarray, x0: float, x1: float, x2: float, p: float
) -> tuple[float, float, float]:
    """``Guide.virtual_force`` (not done), with ``v = v_ref``."""
    k_s = ws[C_K]
    s = ws[S_S]
    clamped = s >= _leg(ws, int(ws[S_LEG]), 1)
    i, t = locate(path, s, clamped)
    xd0, xd1, xd2, b0, b1, b2, k0, k1, k2, curved = frame(path, i, t)
    f0, f1, f2 = k_s * (xd0 - x0), k_s * (xd1 - x1), k_s * (xd2 - x2)
    if clamped:
        return f0, f1, f2
    fp = ws[C_FPROP]
    f0 += fp * b0
    f1 += fp * b1
    f2 += fp * b2
    if curved and ws[C_FFMASS] != 0.0:
        vp = (ws[S_VREF] * b0 + ws[S_VREF + 1] * b1 + ws[S_VREF + 2] * b2) / p
        c = ws[C_FFMASS] * vp * vp
        f0 += c * k0
        f1 += c * k1
        f2 += c * k2
    return f0, f1, f2


@kernel
def _tangent(
    ws: np.ndarray, path: np.ndarray, x0: float, x1: float, x2: float
) -> tuple[float, float, float]:
    """``Guide.tangent(state, x)`` (not done)."""
    leg = int(ws[S_LEG])
    end = _leg(ws, leg, 1)
    s = ws[S_S]
    i, t = locate(path, s, s >= end)
    b0, b1, b2 = unit_tangent(path, i, t)
    if s >= end:
        d0, d1, d2 = _leg(ws, leg, 2) - x0, _leg(ws, leg, 3) - x1, _leg(ws, leg, 4) - x2
        past = -(d0 * b0 + d1 * b1 + d2 * b2)
        if past > 1e-6:
            n = math.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
            return d0 / n, d1 / n, d2 / n
    return b0, b1, b2


@kernel
def _speed_limit(ws: np.ndarray, path: np.ndarray, c0: float, c1: float, c2: float) -> float:
    """``Guide.speed_limit`` (not done)."""
    acc = ws[C_ACC]
    if acc == math.inf:
        return math.inf
    k = int(ws[S_LEG])
    s = ws[S_S]
    end = _leg(ws, k, 1)
    i, t = locate(path, s, s >= end)
    b0, b1, b2 = unit_tangent(path, i, t)
    along = c0 * b0 + c1 * b1 + c2 * b2
    if along * along < _TURNED_COS2 * (c0 * c0 + c1 * c1 + c2 * c2) or along < 0.0:
        return math.sqrt(ws[C_VTURN2])
    room = end - s - _leg(ws, k, 6)
    acc *= GOVERNOR_SHARE
    cap = math.sqrt(ws[C_VTURN2] + 2.0 * acc * (room if room > 0.0 else 0.0))
    if path[i, 0] != 0.0:  # an arc
        bend = math.sqrt(acc * path[i, RADIUS])
        cap = bend if bend < cap else cap
    return cap


@kernel
def _admittance(ws: np.ndarray, f0: float, f1: float, f2: float, p: float, p_dot: float) -> int:
    """``VariableAdmittance.step`` of ``v_ref`` in place; an error code for bad input."""
    dt = ws[C_DT]
    if not 0.0 < p < math.inf:
        return BAD_PACE
    if not math.isfinite(p_dot):
        return BAD_PACE_RATE
    p_end = p + p_dot * dt
    if not p_end > 0.0:
        return BAD_PACE_END
    v0, v1, v2 = ws[S_VREF], ws[S_VREF + 1], ws[S_VREF + 2]
    if not math.isfinite(f0 + f1 + f2):
        return BAD_TOTAL_FORCE
    if not math.isfinite(v0 + v1 + v2):
        return BAD_VELOCITY
    decay = math.exp(-ws[C_DOVERM] * (p + 0.5 * p_dot * dt) * dt)
    inv_d, inv_p = ws[C_INVD], 1.0 / p
    a0, a1, a2 = f0 * inv_d, f1 * inv_d, f2 * inv_d
    ws[S_VREF] = p_end * (a0 + (v0 * inv_p - a0) * decay)
    ws[S_VREF + 1] = p_end * (a1 + (v1 * inv_p - a1) * decay)
    ws[S_VREF + 2] = p_end * (a2 + (v2 * inv_p - a2) * decay)
    return OK


@kernel
def _command(ws: np.ndarray, path: np.ndarray, x0: float, x1: float, x2: float) -> None:
    """The velocity command: ``v_ref`` (capped by the governor while pushed along) followed at
    the acceleration limit, within the safety limits."""
    o0, o1, o2 = x0 - ws[S_PP], x1 - ws[S_PP + 1], x2 - ws[S_PP + 2]
    c0, c1, c2 = ws[S_VCMD], ws[S_VCMD + 1], ws[S_VCMD + 2]
    ws[S_WAS] = 1.0 if (c0 != 0.0 or c1 != 0.0 or c2 != 0.0) else 0.0
    t0, t1, t2 = ws[S_VREF], ws[S_VREF + 1], ws[S_VREF + 2]
    if ws[S_DONE] == 0.0:
        b0, b1, b2 = _tangent(ws, path, x0, x1, x2)
        if ws[S_FMEAS] * b0 + ws[S_FMEAS + 1] * b1 + ws[S_FMEAS + 2] * b2 > 0.0:
            v_max = _speed_limit(ws, path, c0, c1, c2)
            n2 = t0 * t0 + t1 * t1 + t2 * t2
            if not n2 <= v_max * v_max:
                k = v_max / math.sqrt(n2)
                t0, t1, t2 = k * t0, k * t1, k * t2
    d0, d1, d2 = t0 - c0, t1 - c1, t2 - c2
    dv = ws[C_DVMAX]
    d2n = d0 * d0 + d1 * d1 + d2 * d2
    if not d2n <= dv * dv:
        k = dv / math.sqrt(d2n)
        t0, t1, t2 = c0 + k * d0, c1 + k * d1, c2 + k * d2
    c0, c1, c2 = _limit_velocity(ws, t0, t1, t2, o0, o1, o2)
    ws[S_VCMD], ws[S_VCMD + 1], ws[S_VCMD + 2] = c0, c1, c2


@kernel
def control(
    ws: np.ndarray,
    path: np.ndarray,
    aw: np.ndarray,
    ai: np.ndarray,
    jac: np.ndarray,
    xpos: np.ndarray,
    xmat: np.ndarray,
    qpos: np.ndarray,
    qvel: np.ndarray,
    ctrl: np.ndarray,
    qfrc: np.ndarray,
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
        f0, f1, f2: The person's force on the handle (N).
        m0, m1, m2: That force plus the sensor's noise (N); the deadband of
            :meth:`ForceSensor.measure <langenv.robot.force_sensor.ForceSensor.measure>` is
            applied here.
        p, p_dot: Physical pace and its rate.

    Returns:
        :data:`OK`; the arm's ``LIMITS_DUE`` (re-solve, then ``arm.apply``); or a negative
        code for bad input (nothing done for ``BAD_FORCE``).
    """
    norm2 = m0 * m0 + m1 * m1 + m2 * m2
    if not norm2 < math.inf:
        return BAD_FORCE
    norm = math.sqrt(norm2)
    if norm <= ws[C_DEADBAND]:
        m0, m1, m2 = 0.0, 0.0, 0.0
    else:
        g = 1.0 - ws[C_DEADBAND] / norm
        m0, m1, m2 = m0 * g, m1 * g, m2 * g
    ws[S_FMEAS], ws[S_FMEAS + 1], ws[S_FMEAS + 2] = m0, m1, m2
    u = math.sqrt(m0 * m0 + m1 * m1 + m2 * m2) * ws[C_INV_FMAX]
    if u > 1.0:
        u = 1.0
    keep = ws[C_KEEP]
    ws[S_R] = keep * ws[S_R] + (1.0 - keep) * u
    ws[S_C] = 1.0 - ws[S_R]
    x0, x1, x2 = xpos[0], xpos[1], xpos[2]
    if ws[S_DONE] == 0.0:
        _guide_update(ws, path, x0, x1, x2)
        i, t = locate(path, ws[S_S], False)
        ws[S_PP], ws[S_PP + 1], ws[S_PP + 2] = point(path, i, t)
    if ws[S_DONE] != 0.0:
        ws[S_VREF], ws[S_VREF + 1], ws[S_VREF + 2] = 0.0, 0.0, 0.0
    else:
        g0, g1, g2 = _virtual_force(ws, path, x0, x1, x2, p)
        code = _admittance(ws, m0 + g0, m1 + g1, m2 + g2, p, p_dot)
        if code != OK:
            return code
        o0, o1, o2 = x0 - ws[S_PP], x1 - ws[S_PP + 1], x2 - ws[S_PP + 2]
        v0, v1, v2 = _limit_velocity(ws, ws[S_VREF], ws[S_VREF + 1], ws[S_VREF + 2], o0, o1, o2)
        ws[S_VREF], ws[S_VREF + 1], ws[S_VREF + 2] = v0, v1, v2
    _command(ws, path, x0, x1, x2)
    c0, c1, c2 = ws[S_VCMD], ws[S_VCMD + 1], ws[S_VCMD + 2]
    code = arm_kernel.solve(aw, ai, jac, xpos, xmat, qpos, qvel, c0, c1, c2)
    if code != OK:
        return code
    arm_kernel.apply(aw, ai, jac, ctrl, qfrc, f0, f1, f2)
    return OK


@kernel
def observe(
    ws: np.ndarray,
    path: np.ndarray,
    prm: np.ndarray,
    tab: np.ndarray,
    ai: np.ndarray,
    jac: np.ndarray,
    xpos: np.ndarray,
    qpos: np.ndarray,
    qvel: np.ndarray,
    force: float,
) -> int:
    """The tick after the physics step: ``t_x``, the hand's velocity and distance from the
    path, the time, and the safety monitor (``force``: the magnitude on the handle, N).

    Returns:
        The limit breached (``STOP_*``), ``STOP_NONE`` if none.
    """
    c0, c1, c2 = ws[S_VCMD], ws[S_VCMD + 1], ws[S_VCMD + 2]
    if ws[S_DONE] != 0.0:
        moving = c0 != 0.0 or c1 != 0.0 or c2 != 0.0
        if not moving and math.isnan(ws[S_TEND]):
            ws[S_TEND] = ws[S_TIME] + (ws[C_DT] if ws[S_WAS] != 0.0 else 0.0)
        ws[S_TX] = math.sqrt(c0 * c0 + c1 * c1 + c2 * c2) / ws[C_MAXACC]
        ws[S_TAN], ws[S_TAN + 1], ws[S_TAN + 2] = (
            ws[C_END_TAN],
            ws[C_END_TAN + 1],
            ws[C_END_TAN + 2],
        )
    else:
        ws[S_TX] = estimate(
            prm,
            tab,
            path,
            int(ws[S_LEG]),
            ws[S_S],
            False,
            (xpos[0], xpos[1], xpos[2]),
            (ws[S_VREF], ws[S_VREF + 1], ws[S_VREF + 2]),
            (c0, c1, c2),
        )
        b0, b1, b2 = _tangent(ws, path, xpos[0], xpos[1], xpos[2])
        ws[S_TAN], ws[S_TAN + 1], ws[S_TAN + 2] = b0, b1, b2
    nv = qvel.shape[0]
    hv = ws[S_HV : S_HV + 3]  # J_p qvel, as mju_mulMatVec (not BLAS: the same on any CPU)
    mul_mat_vec(hv, jac, qvel, 3, nv)
    speed = math.sqrt(hv[0] * hv[0] + hv[1] * hv[1] + hv[2] * hv[2])
    ws[S_HS] = speed
    dev = dist3(xpos[0], xpos[1], xpos[2], ws[S_PP], ws[S_PP + 1], ws[S_PP + 2])
    ws[S_DEV] = dev
    ws[S_TIME] += ws[C_DT]
    if not force <= ws[C_FMAX]:
        return STOP_FORCE
    if not dev <= ws[C_DMAX]:
        return STOP_DEVIATION
    if not speed <= ws[C_VTRIP]:
        return STOP_SPEED
    if ws[C_HASJL] != 0.0:
        ws[S_MONCD] -= 1.0
        if ws[S_MONCD] <= 0.0:
            n = int(ws[C_NJ])
            bounds = LEGS + LEG_COLS * int(ws[C_NLEGS])
            slack = math.inf
            for j in range(n):
                q = qpos[ai[n + j]]
                lo, hi = q - ws[bounds + 2 * j], ws[bounds + 2 * j + 1] - q
                room = hi if hi < lo else lo
                if not room >= 0.0:
                    return STOP_JOINT
                slack = room if room < slack else slack
            due = int(slack / ws[C_PERTICK])
            ws[S_MONCD] = float(max(1, min(JOINT_CHECK_MAX, due)))
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
    ws: np.ndarray,
    path: np.ndarray,
    aw: np.ndarray,
    ai: np.ndarray,
    jac: np.ndarray,
    xpos: np.ndarray,
    xmat: np.ndarray,
    qpos: np.ndarray,
    qvel: np.ndarray,
    ctrl: np.ndarray,
    qfrc: np.ndarray,
    prm: np.ndarray,
    tab: np.ndarray,
    ptr: np.ndarray,
    f0: float,
    f1: float,
    f2: float,
    m0: float,
    m1: float,
    m2: float,
    p: float,
    p_dot: float,
) -> tuple[int, int]:
    """A whole tick in one call: :func:`control`, :func:`physics`, :func:`observe`.

    Returns:
        ``(control's answer, observe's answer)``; when control's is not :data:`OK` the tick
        stopped there (physics not stepped; observe's answer is :data:`STOP_NONE`) and the caller
        finishes it (``CompiledTick.finish``).
    """
    code = control(
        ws, path, aw, ai, jac, xpos, xmat, qpos, qvel, ctrl, qfrc, f0, f1, f2, m0, m1, m2, p, p_dot
    )
    if code != OK:
        return code, STOP_NONE
    physics(ptr)
    return OK, observe(ws, path, prm, tab, ai, jac, xpos, qpos, qvel, hypot3(f0, f1, f2))
