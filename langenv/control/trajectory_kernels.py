"""A :class:`~langenv.control.trajectory.Trajectory`'s hot-path geometry, compiled.

The compiled twin of :mod:`langenv.control.trajectory`: the path as rows of
:data:`~langenv.control.trajectory.SEGMENT` (:meth:`Trajectory.packed
<langenv.control.trajectory.Trajectory.packed>`); these functions repeat the segments' plain-float
methods (``point``, ``frame``, ``project``), the trajectory's ``locate``, ``tool_angle`` and
``closest_xyz``, operation for operation.
"""

from __future__ import annotations

import math

import numpy as np

from langenv.control.trajectory import SEGMENT
from langenv.kernels import inline, kernel

__all__ = ["closest", "frame", "locate", "point", "project", "tool_angle", "unit_tangent"]

_S = SEGMENT.at
"""Slots of a segment's row (:data:`~langenv.control.trajectory.SEGMENT`)."""


@inline
def _after(path: np.ndarray, col: int, s: float, strict: bool) -> int:
    """Binary search of the sorted column ``col``: how many rows hold a value ``< s``
    (``strict``: bisect_left) or ``<= s`` (bisect_right). Its cost grows with the log of the
    number of segments, so a long path costs a tick about what a short one does."""
    lo, hi = 0, path.shape[0]
    while lo < hi:
        mid = (lo + hi) // 2
        v = path[mid, col]
        if v < s or (not strict and v == s):
            lo = mid + 1
        else:
            hi = mid
    return lo


@inline
def locate(path: np.ndarray, s: float, arriving: bool) -> tuple[int, float]:
    """``Trajectory.locate``: (segment index, local arc length)."""
    n = path.shape[0]
    if arriving:  # bisect_left on the ends
        i = _after(path, _S.s1, s, True)
    else:  # bisect_right on the starts, minus one
        i = _after(path, _S.s0, s, False) - 1
    i = 0 if i < 0 else (n - 1 if i >= n else i)
    t = s - path[i, _S.s0]
    length = path[i, _S.length]
    return i, (0.0 if t < 0.0 else (length if t > length else t))


@inline
def tool_angle(path: np.ndarray, s: float) -> float:
    """``Trajectory.tool_angle``: the tool's running turn at ``s`` (rad)."""
    n = path.shape[0]
    i = _after(path, _S.s0, s, False) - 1
    i = 0 if i < 0 else (n - 1 if i >= n else i)
    t = s - path[i, _S.s0]
    seg_len = path[i, _S.s1] - path[i, _S.s0]
    t = 0.0 if t < 0.0 else (seg_len if t > seg_len else t)
    return path[i, _S.turn0] + path[i, _S.turn_rate] * t


@inline
def point(path: np.ndarray, i: int, t: float) -> tuple[float, float, float]:
    """Segment ``i``'s ``point(t)``."""
    r = path[i]
    if r[_S.kind] == 0.0:
        return (
            r[_S.origin] + t * r[_S.axis1],
            r[_S.origin + 1] + t * r[_S.axis1 + 1],
            r[_S.origin + 2] + t * r[_S.axis1 + 2],
        )
    th = r[_S.sign] * t / r[_S.radius]
    cr, sr = r[_S.radius] * math.cos(th), r[_S.radius] * math.sin(th)
    return (
        r[_S.origin] + cr * r[_S.axis1] + sr * r[_S.axis2],
        r[_S.origin + 1] + cr * r[_S.axis1 + 1] + sr * r[_S.axis2 + 1],
        r[_S.origin + 2] + cr * r[_S.axis1 + 2] + sr * r[_S.axis2 + 2],
    )


@inline
def unit_tangent(path: np.ndarray, i: int, t: float) -> tuple[float, float, float]:
    """Segment ``i``'s ``unit_tangent(t)``."""
    r = path[i]
    if r[_S.kind] == 0.0:
        return r[_S.axis1], r[_S.axis1 + 1], r[_S.axis1 + 2]
    th = r[_S.sign] * t / r[_S.radius]
    cs, sn = r[_S.sign] * math.cos(th), r[_S.sign] * math.sin(th)
    return (
        -sn * r[_S.axis1] + cs * r[_S.axis2],
        -sn * r[_S.axis1 + 1] + cs * r[_S.axis2 + 1],
        -sn * r[_S.axis1 + 2] + cs * r[_S.axis2 + 2],
    )


@inline
def frame(
    path: np.ndarray, i: int, t: float
) -> tuple[float, float, float, float, float, float, float, float, float, bool]:
    """Segment ``i``'s ``frame(t)``: point, unit tangent, curvature vector, and whether it is
    curved (a line's curvature is ``None`` in Python, zeros here)."""
    r = path[i]
    if r[_S.kind] == 0.0:
        x0, x1, x2 = (
            r[_S.origin] + t * r[_S.axis1],
            r[_S.origin + 1] + t * r[_S.axis1 + 1],
            r[_S.origin + 2] + t * r[_S.axis1 + 2],
        )
        return x0, x1, x2, r[_S.axis1], r[_S.axis1 + 1], r[_S.axis1 + 2], 0.0, 0.0, 0.0, False
    radius, sg = r[_S.radius], r[_S.sign]
    th = sg * t / radius
    cs, sn = math.cos(th), math.sin(th)
    k = 1.0 / radius
    r0 = cs * r[_S.axis1] + sn * r[_S.axis2]
    r1 = cs * r[_S.axis1 + 1] + sn * r[_S.axis2 + 1]
    r2 = cs * r[_S.axis1 + 2] + sn * r[_S.axis2 + 2]
    return (
        r[_S.origin] + radius * r0,
        r[_S.origin + 1] + radius * r1,
        r[_S.origin + 2] + radius * r2,
        sg * (-sn * r[_S.axis1] + cs * r[_S.axis2]),
        sg * (-sn * r[_S.axis1 + 1] + cs * r[_S.axis2 + 1]),
        sg * (-sn * r[_S.axis1 + 2] + cs * r[_S.axis2 + 2]),
        -k * r0,
        -k * r1,
        -k * r2,
        True,
    )


@inline
def project(path: np.ndarray, i: int, x0: float, x1: float, x2: float) -> float:
    """Segment ``i``'s ``project``: local arc length of its point closest to ``x`` (m)."""
    r = path[i]
    if r[_S.kind] == 0.0:
        t = (
            (x0 - r[_S.origin]) * r[_S.axis1]
            + (x1 - r[_S.origin + 1]) * r[_S.axis1 + 1]
            + (x2 - r[_S.origin + 2]) * r[_S.axis1 + 2]
        )
        return 0.0 if t < 0.0 else (r[_S.length] if t > r[_S.length] else t)
    d0, d1, d2 = x0 - r[_S.origin], x1 - r[_S.origin + 1], x2 - r[_S.origin + 2]
    u1 = d0 * r[_S.axis1] + d1 * r[_S.axis1 + 1] + d2 * r[_S.axis1 + 2]
    u2 = d0 * r[_S.axis2] + d1 * r[_S.axis2 + 1] + d2 * r[_S.axis2 + 2]
    if u1 == 0.0 and u2 == 0.0:
        return 0.0
    phi = math.atan2(r[_S.sign] * u2, u1)
    if phi < 0.0:
        phi += 2.0 * math.pi
    span = abs(r[_S.angle])
    if phi > span:
        phi = span if phi - span < 2.0 * math.pi - phi else 0.0
    return phi * r[_S.radius]


@inline
def _dist2_on(
    path: np.ndarray, i: int, x0: float, x1: float, x2: float, lo: float, hi: float
) -> tuple[float, float]:
    s0 = path[i, _S.s0]
    s = s0 + project(path, i, x0, x1, x2)
    s = lo if s < lo else (hi if s > hi else s)
    p0, p1, p2 = point(path, i, s - s0)
    d0, d1, d2 = x0 - p0, x1 - p1, x2 - p2
    return s, d0 * d0 + d1 * d1 + d2 * d2


@kernel
def closest(
    path: np.ndarray, x0: float, x1: float, x2: float, s_prev: float, lo: float, hi: float
) -> float:
    """``Trajectory.closest_xyz``: the local closest point by descent from ``s_prev`` (m)."""
    n = path.shape[0]
    s_prev = lo if s_prev < lo else (hi if s_prev > hi else s_prev)
    i = _after(path, _S.s0, s_prev, False) - 1  # the search starts from s_prev's segment
    i = 0 if i < 0 else (n - 1 if i >= n else i)
    best_s, best_d2 = _dist2_on(path, i, x0, x1, x2, lo, hi)
    eps = 1e-12
    if i > 0 and s_prev <= path[i, _S.s0] + eps and path[i, _S.s0] > lo:
        s, d2 = _dist2_on(path, i - 1, x0, x1, x2, lo, hi)
        if d2 < best_d2:
            best_s, best_d2, i = s, d2, i - 1
    j = i
    moved = False
    while j + 1 < n and best_s >= path[j, _S.s1] - eps and path[j, _S.s1] < hi:
        s, d2 = _dist2_on(path, j + 1, x0, x1, x2, lo, hi)
        if d2 < best_d2 - eps * eps:
            best_s, best_d2 = s, d2
            j += 1
            moved = True
        else:
            break
    if not moved:
        j = i
        while j > 0 and best_s <= path[j, _S.s0] + eps and path[j, _S.s0] > lo:
            s, d2 = _dist2_on(path, j - 1, x0, x1, x2, lo, hi)
            if d2 < best_d2 - eps * eps:
                best_s, best_d2 = s, d2
                j -= 1
            else:
                break
    return best_s
