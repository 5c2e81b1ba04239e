"""The arm's velocity controller C (:class:`~langenv.robot.arm.Arm`), compiled.

``aw`` holds the controller's settings, state and work arrays (float64, declared by
:data:`~langenv.robot.arm.ARM`, then the per-joint blocks of
:data:`~langenv.robot.arm.ARM_JOINTS`, ``n`` joints, and the task Jacobian, task size ``k`` = 3
or 6; packed by :meth:`Arm.compiled_arrays <langenv.robot.arm.Arm.compiled_arrays>`); ``ai`` the
joints' dof and qpos addresses and their actuators (int64, ``3 n``). :func:`solve` is the
Cartesian command and the damped least squares up to the joint-limit check; :func:`apply` the
joint speed limit, the reference point, ``ctrl`` and ``qfrc_applied``.
"""

from __future__ import annotations

import math

import numpy as np

from langenv.kernels import inline, kernel
from langenv.kernels.blas import chol_factor, chol_solve, mul_mat_t_vec, mul_mat_vec, sqr_mat_t
from langenv.robot.arm import ARM, ARM_JOINTS

__all__ = ["LIMITS_DUE", "OK", "apply", "solve"]

_A = ARM.at
_J0 = ARM.size
"""Start of the per-joint blocks (:data:`~langenv.robot.arm.ARM_JOINTS`), then the task Jacobian."""
_J = ARM_JOINTS.at
_NJ = len(ARM_JOINTS.fields)

OK = 0
LIMITS_DUE = 1
""":func:`solve`'s answer when a joint is inside its limit margin: Python re-solves
(``Arm._avoid_limits``) before :func:`apply`."""


@kernel
def _joint(aw: np.ndarray, block: int, i: int) -> float:
    n = int(aw[_A.n])
    return aw[_J0 + block * n + i]


@inline
def _damped_least_squares(
    aw: np.ndarray, jarm: np.ndarray, xdot: np.ndarray, qdot: np.ndarray, k: int, n: int
) -> None:
    """``qdot = J^T (J J^T + lambda^2 I)^-1 xdot`` (``Arm.step``'s 3: MuJoCo's routines, in
    their order), ``J = jarm`` (k, n). Inlined, so a call with constant sizes is compiled for
    them (loops unrolled, the same operations)."""
    a = aw[_A.a : _A.a + k * k]
    sqr_mat_t(a, jarm, k, n)
    for i in range(k):
        a[i * (k + 1)] += aw[_A.lambda2]
    chol_factor(a, k, 0.0)
    y = aw[_A.y : _A.y + k]
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

    ``v`` is the commanded hand velocity (finite); the clipped one is kept in ``aw[_A.v:]``.
    Returns :data:`LIMITS_DUE` when a joint is inside its margin, else :data:`OK`.
    """
    n, k, nv = int(aw[_A.n]), int(aw[_A.task]), int(aw[_A.nv])
    vmax, kp, emax2 = aw[_A.v_max], aw[_A.kp], aw[_A.e_max2]
    s2 = v0 * v0 + v1 * v1 + v2 * v2
    if s2 > vmax * vmax:
        f = vmax / math.sqrt(s2)
        v0, v1, v2 = v0 * f, v1 * f, v2 * f
    aw[_A.v], aw[_A.v + 1], aw[_A.v + 2] = v0, v1, v2
    # Cartesian command: v + kp (x_ref - x), orientation hold
    e0 = aw[_A.x_ref] - xpos[0]
    e1 = aw[_A.x_ref + 1] - xpos[1]
    e2_ = aw[_A.x_ref + 2] - xpos[2]
    e2 = e0 * e0 + e1 * e1 + e2_ * e2_
    if e2 > emax2:
        f = aw[_A.e_max] / math.sqrt(e2)
        e0, e1, e2_ = e0 * f, e1 * f, e2_ * f
        aw[_A.x_ref], aw[_A.x_ref + 1], aw[_A.x_ref + 2] = xpos[0] + e0, xpos[1] + e1, xpos[2] + e2_
    x0, x1, x2 = e0 * kp + v0, e1 * kp + v1, e2_ * kp + v2
    if math.sqrt(s2) + kp * math.sqrt(e2 if e2 < emax2 else emax2) > vmax:
        c2 = x0 * x0 + x1 * x1 + x2 * x2
        if c2 > vmax * vmax:
            f = vmax / math.sqrt(c2)
            x0, x1, x2 = x0 * f, x1 * f, x2 * f
    xdot = aw[_A.xdot : _A.xdot + 6]
    xdot[0], xdot[1], xdot[2] = x0, x1, x2
    if k == 6:
        mul_mat_vec(xdot[3:6], aw[_A.rot_b : _A.rot_b + 27], xmat, 3, 9)
    # damped least squares on the task Jacobian
    jarm = aw[_J0 + _NJ * n : _J0 + _NJ * n + k * n]
    if aw[_A.full_dofs] != 0.0:
        for i in range(k * nv):
            jarm[i] = jac[i]
    else:
        for r in range(k):
            for i in range(n):
                jarm[r * n + i] = jac[r * nv + ai[i]]
    qdot = aw[_J0 + _J.qdot * n : _J0 + (_J.qdot + 1) * n]
    if k == 6 and n == 6:  # the UR5 holding its orientation: sizes the compiler unrolls
        _damped_least_squares(aw, jarm, xdot, qdot, 6, 6)
    else:
        _damped_least_squares(aw, jarm, xdot, qdot, k, n)
    # joint-limit margins: checked only when a joint could have reached one
    aw[_A.countdown] -= 1.0
    if aw[_A.countdown] <= 0.0:
        if aw[_A.has_limits] == 0.0:
            aw[_A.countdown] = float(1 << 62)
            return OK
        slack = math.inf
        for i in range(n):
            q = qpos[ai[n + i]]
            lo = q - _joint(aw, _J.lower_margin, i)
            hi = _joint(aw, _J.upper_margin, i) - q
            m = hi if hi < lo else lo
            slack = m if m < slack else slack
        if slack <= 0.0:
            aw[_A.countdown] = 1.0
            return LIMITS_DUE
        top = 0.0
        for i in range(n):
            w = abs(qvel[ai[i]]) * _joint(aw, _J.inv_qd_max, i)
            top = w if w > top or i == 0 else top
        bound = 2.0 * (top if top > 1.0 else 1.0) * aw[_A.max_qd]
        due = int(slack / (bound * aw[_A.dt]))
        aw[_A.countdown] = float(max(1, min(25, due)))
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
    n, nv = int(aw[_A.n]), int(aw[_A.nv])
    qdot = aw[_J0 + _J.qdot * n : _J0 + (_J.qdot + 1) * n]
    scale = aw[_A.dt]
    t2 = 0.0
    for i in range(n):
        t = qdot[i] * _joint(aw, _J.inv_qd_max, i)
        t2 += t * t
    if t2 > 1.0:
        ratio = 0.0
        for i in range(n):
            t = abs(qdot[i] * _joint(aw, _J.inv_qd_max, i))
            ratio = t if t > ratio else ratio
        if ratio > 1.0:
            inv = 1.0 / ratio
            for i in range(n):
                qdot[i] *= inv
            scale /= ratio
    for c in range(3):
        aw[_A.x_ref + c] += aw[_A.v + c] * scale
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
