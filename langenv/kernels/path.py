"""A :class:`~langenv.control.trajectory.Trajectory` as an array, and its hot-path geometry.

:func:`pack` turns the segments into one row each (:data:`COLS` columns); the compiled functions
repeat the segments' plain-float methods (``point``, ``frame``, ``project``), the trajectory's
``locate``, ``tool_angle`` and ``closest_xyz``, operation for operation.
"""

from __future__ import annotations

import math

import numpy as np

from langenv.control.trajectory import ArcSegment, Trajectory
from langenv.kernels import inline, kernel

__all__ = ["COLS", "closest", "frame", "locate", "pack", "point", "tool_angle", "unit_tangent"]

# columns of a segment's row
KIND, S0, S1, LEN, TURN0, TURN_RATE, P0, U, C, E1, E2, RADIUS, SIGN, ANGLE = (
    0,
    1,
    2,
    3,
    4,
    5,
    6,
    9,
    6,
    9,
    12,
    15,
    16,
    17,
)
COLS = 18
"""Columns of a packed segment: kind (0 line, 1 arc), start and end arc length, length, tool
turn at the start and per metre, then the line's start point and direction or the arc's centre,
``e1``, ``e2``, radius, sign and angle."""


def pack(trajectory: Trajectory) -> np.ndarray:
    """The trajectory's segments as rows, shape ``(n, COLS)``, float64."""
    n = len(trajectory.segments)
    rows = np.zeros((n, COLS))
    for i, seg in enumerate(trajectory.segments):
        row = rows[i]
        row[S0], row[S1] = trajectory._starts[i], trajectory._ends[i]
        row[LEN] = seg.length
        row[TURN0], row[TURN_RATE] = trajectory._turn_start[i], trajectory._turn_rate[i]
        if isinstance(seg, ArcSegment):
            row[KIND] = 1.0
            row[C : C + 3], row[E1 : E1 + 3], row[E2 : E2 + 3] = seg._c, seg._e1, seg._e2
            row[RADIUS], row[SIGN], row[ANGLE] = seg.radius, seg._sign, seg.angle
        else:
            row[P0 : P0 + 3], row[U : U + 3] = seg._p0, seg._u
    return rows


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
        i = _after(path, S1, s, True)
    else:  # bisect_right on the starts, minus one
        i = _after(path, S0, s, False) - 1
    i = 0 if i < 0 else (n - 1 if i >= n else i)
    t = s - path[i, S0]
    length = path[i, LEN]
    return i, (0.0 if t < 0.0 else (length if t > length else t))


@inline
def tool_angle(path: np.ndarray, s: float) -> float:
    """``Trajectory.tool_angle``: the tool's running turn at ``s`` (rad)."""
    n = path.shape[0]
    i = _after(path, S0, s, False) - 1
    i = 0 if i < 0 else (n - 1 if i >= n else i)
    t = s - path[i, S0]
    seg_len = path[i, S1] - path[i, S0]
    t = 0.0 if t < 0.0 else (seg_len if t > seg_len else t)
    return path[i, TURN0] + path[i, TURN_RATE] * t


@inline
def point(path: np.ndarray, i: int, t: float) -> tuple[float, float, float]:
    """Segment ``i``'s ``point(t)``."""
    r = path[i]
    if r[KIND] == 0.0:
        return r[P0] + t * r[U], r[P0 + 1] + t * r[U + 1], r[P0 + 2] + t * r[U + 2]
    th = r[SIGN] * t / r[RADIUS]
    cr, sr = r[RADIUS] * math.cos(th), r[RADIUS] * math.sin(th)
    return (
        r[C] + cr * r[E1] + sr * r[E2],
        r[C + 1] + cr * r[E1 + 1] + sr * r[E2 + 1],
        r[C + 2] + cr * r[E1 + 2] + sr * r[E2 + 2],
    )


@inline
def unit_tangent(path: np.ndarray, i: int, t: float) -> tuple[float, float, float]:
    """Segment ``i``'s ``unit_tangent(t)``."""
    r = path[i]
    if r[KIND] == 0.0:
        return r[U], r[U + 1], r[U + 2]
    th = r[SIGN] * t / r[RADIUS]
    cs, sn = r[SIGN] * math.cos(th), r[SIGN] * math.sin(th)
    return (
        -sn * r[E1] + cs * r[E2],
        -sn * r[E1 + 1] + cs * r[E2 + 1],
        -sn * r[E1 + 2] + cs * r[E2 + 2],
    )


@inline
def frame(
    path: np.ndarray, i: int, t: float
) -> tuple[float, float, float, float, float, float, float, float, float, bool]:
    """Segment ``i``'s ``frame(t)``: point, unit tangent, curvature vector, and whether it is
    curved (a line's curvature is ``None`` in Python, zeros here)."""
    r = path[i]
    if r[KIND] == 0.0:
        x0, x1, x2 = r[P0] + t * r[U], r[P0 + 1] + t * r[U + 1], r[P0 + 2] + t * r[U + 2]
        return x0, x1, x2, r[U], r[U + 1], r[U + 2], 0.0, 0.0, 0.0, False
    radius, sg = r[RADIUS], r[SIGN]
    th = sg * t / radius
    cs, sn = math.cos(th), math.sin(th)
    k = 1.0 / radius
    r0 = cs * r[E1] + sn * r[E2]
    r1 = cs * r[E1 + 1] + sn * r[E2 + 1]
    r2 = cs * r[E1 + 2] + sn * r[E2 + 2]
    return (
        r[C] + radius * r0,
        r[C + 1] + radius * r1,
        r[C + 2] + radius * r2,
        sg * (-sn * r[E1] + cs * r[E2]),
        sg * (-sn * r[E1 + 1] + cs * r[E2 + 1]),
        sg * (-sn * r[E1 + 2] + cs * r[E2 + 2]),
        -k * r0,
        -k * r1,
        -k * r2,
        True,
    )


@inline
def project(path: np.ndarray, i: int, x0: float, x1: float, x2: float) -> float:
    """Segment ``i``'s ``project``: local arc length of its point closest to ``x`` (m)."""
    r = path[i]
    if r[KIND] == 0.0:
        t = (x0 - r[P0]) * r[U] + (x1 - r[P0 + 1]) * r[U + 1] + (x2 - r[P0 + 2]) * r[U + 2]
        return 0.0 if t < 0.0 else (r[LEN] if t > r[LEN] else t)
    d0, d1, d2 = x0 - r[C], x1 - r[C + 1], x2 - r[C + 2]
    u1 = d0 * r[E1] + d1 * r[E1 + 1] + d2 * r[E1 + 2]
    u2 = d0 * r[E2] + d1 * r[E2 + 1] + d2 * r[E2 + 2]
    if u1 == 0.0 and u2 == 0.0:
        return 0.0
    phi = math.atan2(r[SIGN] * u2, u1)
    if phi < 0.0:
        phi += 2.0 * math.pi
    span = abs(r[ANGLE])
    if phi > span:
        phi = span if phi - span < 2.0 * math.pi - phi else 0.0
    return phi * r[RADIUS]


@inline
def _dist2_on(
    path: np.ndarray, i: int, x0: float, x1: float, x2: float, lo: float, hi: float
) -> tuple[float, float]:
    s0 = path[i, S0]
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
    i = _after(path, S0, s_prev, False) - 1  # the search starts from s_prev's segment
    i = 0 if i < 0 else (n - 1 if i >= n else i)
    best_s, best_d2 = _dist2_on(path, i, x0, x1, x2, lo, hi)
    eps = 1e-12
    if i > 0 and s_prev <= path[i, S0] + eps and path[i, S0] > lo:
        s, d2 = _dist2_on(path, i - 1, x0, x1, x2, lo, hi)
        if d2 < best_d2:
            best_s, best_d2, i = s, d2, i - 1
    j = i
    moved = False
    while j + 1 < n and best_s >= path[j, S1] - eps and path[j, S1] < hi:
        s, d2 = _dist2_on(path, j + 1, x0, x1, x2, lo, hi)
        if d2 < best_d2 - eps * eps:
            best_s, best_d2 = s, d2
            j += 1
            moved = True
        else:
            break
    if not moved:
        j = i
        while j > 0 and best_s <= path[j, S0] + eps and path[j, S0] > lo:
            s, d2 = _dist2_on(path, j - 1, x0, x1, x2, lo, hi)
            if d2 < best_d2 - eps * eps:
                best_s, best_d2 = s, d2
                j -= 1
            else:
                break
    return best_s
