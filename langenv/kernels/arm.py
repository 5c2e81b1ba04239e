"""The arm's velocity controller C (:class:`~langenv.robot.arm.Arm`), compiled.

``aw`` holds the controller's settings, state and work arrays (float64, layout below: the
per-joint blocks start at :data:`J0`, ``n`` joints, task size ``k`` = 3 or 6); ``ai`` the
joints' dof and qpos addresses and their actuators (int64, ``3 n``). :func:`solve` is the
Cartesian command and the damped least squares up to the joint-limit check; :func:`apply` the
joint speed limit, the reference point, ``ctrl`` and ``qfrc_applied``.
"""

from __future__ import annotations

import math

import numpy as np

from langenv.kernels import inline, kernel
from langenv.kernels.blas import chol_factor, chol_solve, mul_mat_t_vec, mul_mat_vec, sqr_mat_t

__all__ = ["J0", "LIMITS_DUE", "OK", "apply", "solve"]

# settings and state
A_VMAX, A_KP, A_EMAX, A_EMAX2, A_LAMBDA2, A_DT, A_TASK, A_N, A_NV = 0, 1, 2, 3, 4, 5, 6, 7, 8
A_HASLIM, A_COUNTDOWN, A_FULL, A_MAXQD = 9, 10, 11, 12
A_XREF, A_ROTB, A_A, A_XDOT, A_Y, A_V = 13, 16, 43, 79, 85, 91  # (3), (27), (36), (6), (6), (3)
J0 = 94
"""Start of the per-joint blocks: 1 / max joint speed, lower and upper limits, limits minus and
plus the margin, ``qdot`` (``n`` each), then the task Jacobian (``k n``)."""

OK = 0
LIMITS_DUE = 1
""":func:`solve`'s answer when a joint is inside its limit margin: Python re-solves
(``Arm._avoid_limits``) before :func:`apply`."""


@kernel
def _joint(aw: np.ndarray, block: int, i: int) -> float:
    n = int(aw[A_N])
    return aw[J0 + block * n + i]


@inline
def _damped_least_squares(
    aw: np.ndarray, jarm: np.ndarray, xdot: np.ndarray, qdot: np.ndarray, k: int, n: int
) -> None:
    """``qdot = J^T (J J^T + lambda^2 I)^-1 xdot`` (``Arm.step``'s 3: MuJoCo's routines, in
    their order), ``J = jarm`` (k, n). Inlined, so a call with constant sizes is compiled for
    them (loops unrolled, the same operations)."""
    a = aw[A_A : A_A + k * k]
    sqr_mat_t(a, jarm, k, n)
    for i in range(k):
        a[i * (k + 1)] += aw[A_LAMBDA2]
    chol_factor(a, k, 0.0)
    y = aw[A_Y : A_Y + k]
    chol_solve(y, a, xdot[:k], k)
    mul_mat_t_vec(qdot, jarm, y, k, n)


@kernel
def solve(
    aw: np.ndarray,
    ai: np.ndarray,
    jac: np.ndarray,
    xpos: np.ndarray,
    xmat: np.ndarray,
    qpos: np.ndarray,
    qvel: np.ndarray,
    v0: float,
    v1: float,
    v2: float,
) -> int:
    """Cartesian command and damped least squares: ``qdot`` in ``aw`` (``Arm.step``, 1-3).

    ``v`` is the commanded hand velocity (finite); the clipped one is kept in ``aw[A_V:]``.
    Returns :data:`LIMITS_DUE` when a joint is inside its margin, else :data:`OK`.
    """
    n, k, nv = int(aw[A_N]), int(aw[A_TASK]), int(aw[A_NV])
    vmax, kp, emax2 = aw[A_VMAX], aw[A_KP], aw[A_EMAX2]
    s2 = v0 * v0 + v1 * v1 + v2 * v2
    if s2 > vmax * vmax:
        f = vmax / math.sqrt(s2)
        v0, v1, v2 = v0 * f, v1 * f, v2 * f
    aw[A_V], aw[A_V + 1], aw[A_V + 2] = v0, v1, v2
    # Cartesian command: v + kp (x_ref - x), orientation hold
    e0 = aw[A_XREF] - xpos[0]
    e1 = aw[A_XREF + 1] - xpos[1]
    e2_ = aw[A_XREF + 2] - xpos[2]
    e2 = e0 * e0 + e1 * e1 + e2_ * e2_
    if e2 > emax2:
        f = aw[A_EMAX] / math.sqrt(e2)
        e0, e1, e2_ = e0 * f, e1 * f, e2_ * f
        aw[A_XREF], aw[A_XREF + 1], aw[A_XREF + 2] = xpos[0] + e0, xpos[1] + e1, xpos[2] + e2_
    x0, x1, x2 = e0 * kp + v0, e1 * kp + v1, e2_ * kp + v2
    if math.sqrt(s2) + kp * math.sqrt(e2 if e2 < emax2 else emax2) > vmax:
        c2 = x0 * x0 + x1 * x1 + x2 * x2
        if c2 > vmax * vmax:
            f = vmax / math.sqrt(c2)
            x0, x1, x2 = x0 * f, x1 * f, x2 * f
    xdot = aw[A_XDOT : A_XDOT + 6]
    xdot[0], xdot[1], xdot[2] = x0, x1, x2
    if k == 6:
        mul_mat_vec(xdot[3:6], aw[A_ROTB : A_ROTB + 27], xmat, 3, 9)
    # damped least squares on the task Jacobian
    jarm = aw[J0 + 6 * n : J0 + 6 * n + k * n]
    if aw[A_FULL] != 0.0:
        for i in range(k * nv):
            jarm[i] = jac[i]
    else:
        for r in range(k):
            for i in range(n):
                jarm[r * n + i] = jac[r * nv + ai[i]]
    qdot = aw[J0 + 5 * n : J0 + 6 * n]
    if k == 6 and n == 6:  # the UR5 holding its orientation: sizes the compiler unrolls
        _damped_least_squares(aw, jarm, xdot, qdot, 6, 6)
    else:
        _damped_least_squares(aw, jarm, xdot, qdot, k, n)
    # joint-limit margins: checked only when a joint could have reached one
    aw[A_COUNTDOWN] -= 1.0
    if aw[A_COUNTDOWN] <= 0.0:
        if aw[A_HASLIM] == 0.0:
            aw[A_COUNTDOWN] = float(1 << 62)
            return OK
        slack = math.inf
        for i in range(n):
            q = qpos[ai[n + i]]
            lo = q - _joint(aw, 3, i)
            hi = _joint(aw, 4, i) - q
            m = hi if hi < lo else lo
            slack = m if m < slack else slack
        if slack <= 0.0:
            aw[A_COUNTDOWN] = 1.0
            return LIMITS_DUE
        top = 0.0
        for i in range(n):
            w = abs(qvel[ai[i]]) * _joint(aw, 0, i)
            top = w if w > top or i == 0 else top
        bound = 2.0 * (top if top > 1.0 else 1.0) * aw[A_MAXQD]
        due = int(slack / (bound * aw[A_DT]))
        aw[A_COUNTDOWN] = float(max(1, min(25, due)))
    return OK


@kernel
def apply(
    aw: np.ndarray,
    ai: np.ndarray,
    jac: np.ndarray,
    ctrl: np.ndarray,
    qfrc: np.ndarray,
    f0: float,
    f1: float,
    f2: float,
) -> None:
    """Joint speed limit, reference point, ``ctrl`` and ``qfrc_applied = J_p^T F`` (4-6)."""
    n, nv = int(aw[A_N]), int(aw[A_NV])
    qdot = aw[J0 + 5 * n : J0 + 6 * n]
    scale = aw[A_DT]
    t2 = 0.0
    for i in range(n):
        t = qdot[i] * _joint(aw, 0, i)
        t2 += t * t
    if t2 > 1.0:
        ratio = 0.0
        for i in range(n):
            t = abs(qdot[i] * _joint(aw, 0, i))
            ratio = t if t > ratio else ratio
        if ratio > 1.0:
            inv = 1.0 / ratio
            for i in range(n):
                qdot[i] *= inv
            scale /= ratio
    for c in range(3):
        aw[A_XREF + c] += aw[A_V + c] * scale
    for i in range(n):
        ctrl[ai[2 * n + i]] = qdot[i]
    # qfrc_applied = J_p^T f: mju_mulMatTVec's operations, ``f`` given as three numbers
    for j in range(nv):
        qfrc[j] = 0.0
    for r in range(3):
        v = f0 if r == 0 else (f1 if r == 1 else f2)
        if v != 0.0:
            for j in range(nv):
                qfrc[j] += jac[r * nv + j] * v
