"""The guide compiled (:class:`~langenv.control.guide.Guide`): closest point and leg switching,
the virtual force, the direction of progress and the speed governor.

Pure functions of the guide's state (``s``, ``leg``), the packed path
(:meth:`Trajectory.packed <langenv.control.trajectory.Trajectory.packed>`) and the legs (rows of
:data:`~langenv.control.guide.LEG`, flat: :meth:`Guide.leg_rows
<langenv.control.guide.Guide.leg_rows>`); the same operations in the same order as the methods
of :class:`~langenv.control.guide.Guide` (``update``, ``virtual_force``, ``tangent``,
``speed_limit``), so the results are bit-identical (``tests/test_compiled_tick.py``).
"""

from __future__ import annotations

import math

import numpy as np

from langenv.control.guide import GOVERNOR_SHARE, LEG, TURNED_COS2
from langenv.control.trajectory import SEGMENT
from langenv.control.trajectory_kernels import closest, frame, locate, tool_angle, unit_tangent
from langenv.kernels import inline, kernel

__all__ = ["leg_value", "speed_limit", "tangent", "update", "virtual_force"]

_L = LEG.at
_W = LEG.size
_RADIUS = SEGMENT.at.radius
_KIND = SEGMENT.at.kind


@inline
def leg_value(legs: np.ndarray, k: int, col: int) -> float:
    """Column ``col`` (a slot of :data:`~langenv.control.guide.LEG`) of leg ``k``."""
    return legs[_W * k + col]


@kernel
def update(
    path: np.ndarray,
    legs: np.ndarray,
    s: float,
    leg: int,
    n_legs: int,
    tol2: float,
    x0: float,
    x1: float,
    x2: float,
) -> tuple[float, int, bool]:
    """``Guide.update`` (not done): the closest point in the leg, the next leg (or done) near
    its end pose once the closest point has reached the leg's gate; returns ``(s, leg, done)``."""
    k = leg
    s_end = leg_value(legs, k, _L.end)
    s = closest(path, x0, x1, x2, s, leg_value(legs, k, _L.start), s_end)
    d0 = x0 - leg_value(legs, k, _L.end_point)
    d1 = x1 - leg_value(legs, k, _L.end_point + 1)
    d2 = x2 - leg_value(legs, k, _L.end_point + 2)
    dphi = leg_value(legs, k, _L.end_angle) - tool_angle(path, s)
    done = False
    if d0 * d0 + d1 * d1 + d2 * d2 + dphi * dphi < tol2 and s >= leg_value(legs, k, _L.gate):
        leg = k + 1
        if k + 1 >= n_legs:
            done = True
            s = s_end
    return s, leg, done


@kernel
def virtual_force(
    path: np.ndarray,
    legs: np.ndarray,
    s: float,
    leg: int,
    k_s: float,
    f_prop: float,
    ff_mass: float,
    x0: float,
    x1: float,
    x2: float,
    v0: float,
    v1: float,
    v2: float,
    p: float,
) -> tuple[float, float, float]:
    """``Guide.virtual_force`` (not done), ``v`` the reference velocity."""
    clamped = s >= leg_value(legs, leg, _L.end)
    i, t = locate(path, s, clamped)
    xd0, xd1, xd2, b0, b1, b2, k0, k1, k2, curved = frame(path, i, t)
    f0, f1, f2 = k_s * (xd0 - x0), k_s * (xd1 - x1), k_s * (xd2 - x2)
    if clamped:
        return f0, f1, f2
    fp = f_prop
    f0 += fp * b0
    f1 += fp * b1
    f2 += fp * b2
    if curved and ff_mass != 0.0:
        vp = (v0 * b0 + v1 * b1 + v2 * b2) / p
        c = ff_mass * vp * vp
        f0 += c * k0
        f1 += c * k1
        f2 += c * k2
    return f0, f1, f2


@kernel
def tangent(
    path: np.ndarray, legs: np.ndarray, s: float, leg: int, x0: float, x1: float, x2: float
) -> tuple[float, float, float]:
    """``Guide.tangent(state, x)`` (not done)."""
    end = leg_value(legs, leg, _L.end)
    i, t = locate(path, s, s >= end)
    b0, b1, b2 = unit_tangent(path, i, t)
    if s >= end:
        d0 = leg_value(legs, leg, _L.end_point) - x0
        d1 = leg_value(legs, leg, _L.end_point + 1) - x1
        d2 = leg_value(legs, leg, _L.end_point + 2) - x2
        past = -(d0 * b0 + d1 * b1 + d2 * b2)
        if past > 1e-6:
            n = math.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
            return d0 / n, d1 / n, d2 / n
    return b0, b1, b2


@kernel
def speed_limit(
    path: np.ndarray,
    legs: np.ndarray,
    s: float,
    leg: int,
    acc: float,
    v_turn2: float,
    c0: float,
    c1: float,
    c2: float,
) -> float:
    """``Guide.speed_limit`` (not done), ``c`` the velocity command now."""
    if acc == math.inf:
        return math.inf
    end = leg_value(legs, leg, _L.end)
    i, t = locate(path, s, s >= end)
    b0, b1, b2 = unit_tangent(path, i, t)
    along = c0 * b0 + c1 * b1 + c2 * b2
    if along * along < TURNED_COS2 * (c0 * c0 + c1 * c1 + c2 * c2) or along < 0.0:
        return math.sqrt(v_turn2)
    room = end - s - leg_value(legs, leg, _L.switch)
    acc *= GOVERNOR_SHARE
    cap = math.sqrt(v_turn2 + 2.0 * acc * (room if room > 0.0 else 0.0))
    if path[i, _KIND] != 0.0:  # an arc
        bend = math.sqrt(acc * path[i, _RADIUS])
        cap = bend if bend < cap else cap
    return cap
