"""Rotation helpers of the arm's orientation hold: the linear error map and the rotation vector."""

from __future__ import annotations

import mujoco
import numpy as np
from numpy.typing import NDArray

__all__ = ["rotation_error_matrix", "rotation_vector"]


def rotation_error_matrix(r_held: NDArray[np.float64], gain: float) -> NDArray[np.float64]:
    """The (3, 9) matrix B with ``B @ R.ravel() = gain * 1/2 sum_i r_i x r0_i``.

    ``1/2 sum_i r_i x r0_i`` (``r_i``, ``r0_i``: columns of the current and held rotation) equals
    the rotation vector from ``R`` to the held rotation for small errors and is linear in ``R``,
    so the arm's orientation command is one matrix-vector product per tick.

    Args:
        r_held: (3, 3) rotation to hold (columns ``r0_i``), world frame.
        gain: scale folded into B (1/s for an angular-velocity command).

    Returns:
        (3, 9) float64; ``R.ravel()`` is row-major, so entry ``3 a + i`` is ``R[a, i]``.
    """
    b = np.zeros((3, 9))
    k = 0.5 * gain
    for a in range(3):
        e_a = [0.0, 0.0, 0.0]
        e_a[a] = 1.0
        for i in range(3):
            b[:, 3 * a + i] = [k * c for c in _cross(e_a, r_held[:, i].tolist())]
    return b


def _cross(u: list[float], v: list[float]) -> tuple[float, float, float]:
    """``np.cross(u, v)`` of two 3-vectors, its operations in its order (signed zeros
    included), on Python floats: a few microseconds instead of NumPy's ~40 per call."""
    return (
        u[1] * v[2] - u[2] * v[1],
        u[2] * v[0] - u[0] * v[2],
        u[0] * v[1] - u[1] * v[0],
    )


def rotation_vector(r_from: NDArray[np.float64], r_to: NDArray[np.float64]) -> NDArray[np.float64]:
    """Rotation vector taking ``r_from`` to ``r_to``.

    Args:
        r_from: (3, 3) rotation matrix, world frame.
        r_to: (3, 3) rotation matrix, world frame.

    Returns:
        (3,) float64, axis * angle (rad), world frame.
    """
    rel = np.empty((3, 3))  # r_to @ r_from.T in MuJoCo's fixed order (no BLAS: same on any CPU)
    mujoco.mju_mulMatMatT(rel, np.ascontiguousarray(r_to), np.ascontiguousarray(r_from))
    quat = np.empty(4)
    mujoco.mju_mat2Quat(quat, rel.ravel())
    vel = np.empty(3)
    mujoco.mju_quat2Vel(vel, quat, 1.0)
    return vel
