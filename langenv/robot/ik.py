"""Position inverse kinematics of the handle site: where :meth:`langenv.robot.Arm.reset` puts it.

Damped Gauss-Newton on the site Jacobian of the controlled joints, from the current ``qpos``,
with a bounded Cartesian step per iteration so that the solution stays on the starting branch
(the UR5's elbow-up home), and joint positions clipped to their limits.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import mujoco
import numpy as np
from numpy.typing import NDArray

from langenv import vec
from langenv.robot.handles import ArmHandles
from langenv.robot.rotation import rotation_vector

__all__ = ["IK_ACCEPT", "solve_ik"]

IK_MAX_ITER = 300
"""Most Gauss-Newton iterations."""
IK_TOL = 1e-9
"""Convergence of the IK step (m / rad)."""
IK_ACCEPT = 1e-4
"""Largest position residual (m) a caller should accept."""
IK_MAX_STEP = 0.05
"""Largest Cartesian step (m) per iteration (stays on the starting branch)."""


def solve_ik(
    model: mujoco.MjModel,
    data: mujoco.MjData,
    handles: ArmHandles,
    jacobian: Callable[[], NDArray[np.float64]],
    target: NDArray[np.float64],
    rotation: NDArray[np.float64] | None,
) -> float:
    """Move ``data.qpos`` so that the handle site reaches ``target`` (and keeps ``rotation``).

    Args:
        model: the arm's model.
        data: its data; ``qpos`` is the start and receives the solution, kinematics are updated.
        handles: the arm's resolved names.
        jacobian: recomputes and returns the (k, n) site Jacobian of the controlled joints at the
            current kinematics (k = 6 with an orientation task, 3 without).
        target: (3,) site position (m, base frame).
        rotation: (3, 3) site orientation to keep, or ``None`` for a position-only task (k = 3).

    Returns:
        Final position residual (m).
    """
    site_xpos = data.site_xpos[handles.site_id]
    site_xmat = data.site_xmat[handles.site_id]
    k = 3 if rotation is None else 6
    err = np.zeros(k)
    residual = math.inf
    for _ in range(IK_MAX_ITER):
        mujoco.mj_kinematics(model, data)
        mujoco.mj_comPos(model, data)
        jac = jacobian()
        err[:3] = target - site_xpos
        residual = vec.norm(err[:3])
        step = err[:3] * min(1.0, IK_MAX_STEP / max(residual, 1e-300))
        err[:3] = step
        if rotation is not None:
            err[3:] = rotation_vector(site_xmat.reshape(3, 3), rotation)
        if vec.norm(err) < IK_TOL:
            break
        q = data.qpos[handles.qadr] + _damped_step(jac, err)
        data.qpos[handles.qadr] = np.clip(q, handles.lower, handles.upper)
    mujoco.mj_kinematics(model, data)
    return vec.norm(target - site_xpos)


def _damped_step(jac: NDArray[np.float64], err: NDArray[np.float64]) -> NDArray[np.float64]:
    """``J' (J J' + 1e-8 I)^-1 err`` for the (k, n) Jacobian ``jac`` and the (k,) error, by
    MuJoCo's dense routines (Cholesky), whose order of operations does not depend on the CPU."""
    k, n = jac.shape
    jac = np.ascontiguousarray(jac)
    a = np.empty((k, k))
    mujoco.mju_mulMatMatT(a, jac, jac)
    a[np.diag_indices_from(a)] += 1e-8
    mujoco.mju_cholFactor(a, 0.0)
    y = np.empty(k)
    mujoco.mju_cholSolve(y, a, np.ascontiguousarray(err))
    dq = np.empty(n)
    mujoco.mju_mulMatTVec(dq, jac, y)
    return dq
