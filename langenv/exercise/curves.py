"""Smooth curves fitted with lines and circular arcs (biarcs), within a stated tolerance.

An exercise's ``spline`` leg runs through points; the path the guide and the compiled tick
follow is still made of the two segment kinds of :mod:`langenv.control.trajectory` (one source
per shape, SPEC §8): the curve is a cubic spline through the points, parametrised by chord length
(:class:`scipy.interpolate.CubicSpline`, natural ends), and each of its pieces is replaced by a
*biarc*: two arcs (or lines) that leave the piece's start along its tangent, meet with a common
tangent and arrive at its end along its tangent. So the fitted path is tangent-continuous, and
where a biarc strays more than ``tolerance`` from the spline (checked at
:data:`SAMPLES_PER_PIECE` points of the piece) the piece is halved, at most :data:`MAX_DEPTH`
times. In 3-D each arc lies in its own plane (the plane of its start, start tangent and end).

The biarc: with ``v = P1 - P0`` and unit tangents ``T0``, ``T1``, both arcs' tangent lines meet
at a common distance ``d`` from the ends, ``|v - d (T0 + T1)| = 2 d``, the positive root of
``2 (1 - T0.T1) d^2 + 2 (v.(T0 + T1)) d - v.v = 0``; the joint is the midpoint of
``P0 + d T0`` and ``P1 - d T1``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from langenv.control.trajectory import MIN_LENGTH, ArcSegment, LineSegment, Segment
from langenv.errors import TrajectoryError

__all__ = ["MAX_DEPTH", "SAMPLES_PER_PIECE", "arc_to", "biarc", "fit_spline", "spline_points"]

SAMPLES_PER_PIECE = 24
"""Points of each spline piece at which the fitted biarc's distance is measured."""
MAX_DEPTH = 6
"""Most halvings of one spline piece (a piece becomes at most 2**6 biarcs)."""
_STRAIGHT = 1e-9  # |T x chord| / |chord| below which an arc is a line


def arc_to(start: np.ndarray, tangent: np.ndarray, end: np.ndarray) -> Segment:
    """The circular arc (or line) leaving ``start`` along ``tangent`` and ending at ``end``.

    Args:
        start: Start point, shape (3,), m.
        tangent: Unit tangent at the start, shape (3,).
        end: End point, shape (3,), m.

    Returns:
        A :class:`LineSegment` when ``end - start`` is along ``tangent``, else an
        :class:`ArcSegment` about the normal of the plane through them (its end is ``end`` up to
        rounding).

    Raises:
        TrajectoryError: ``end`` equals ``start``, or lies behind it on the tangent's line.
    """
    chord = end - start
    length = float(np.linalg.norm(chord))
    if length < MIN_LENGTH:
        raise TrajectoryError(f"arc_to: end {end.tolist()} equals start")
    normal = np.cross(tangent, chord)
    sin_ = float(np.linalg.norm(normal)) / length
    cos_ = float(tangent @ chord) / length
    if sin_ < _STRAIGHT:
        if cos_ < 0.0:
            raise TrajectoryError(f"arc_to: end {end.tolist()} lies behind the start's tangent")
        return LineSegment(start, end)
    n = normal / np.linalg.norm(normal)
    inward = np.cross(n, tangent)  # towards the centre
    radius = length * length / (2.0 * float(chord @ inward))
    center = start + radius * inward
    angle = 2.0 * math.atan2(sin_, cos_)
    return ArcSegment(center=center, axis=n, start=start, angle=angle)


def biarc(
    p0: np.ndarray, t0: np.ndarray, p1: np.ndarray, t1: np.ndarray
) -> tuple[Segment, Segment]:
    """Two arcs from ``p0`` (tangent ``t0``) to ``p1`` (tangent ``t1``), tangent where they meet.

    Args:
        p0: Start point, shape (3,), m.
        t0: Unit tangent at the start, shape (3,).
        p1: End point, shape (3,), m.
        t1: Unit tangent at the end, shape (3,).

    Returns:
        The two segments; the second starts at the first's computed end.

    Raises:
        TrajectoryError: a degenerate pair (no positive ``d``).
    """
    v = p1 - p0
    t = t0 + t1
    vt = float(v @ t)
    vv = float(v @ v)
    a = 2.0 * (1.0 - float(t0 @ t1))
    root = vt + math.sqrt(max(vt * vt + a * vv, 0.0))  # d = vv / root: no cancellation
    if root <= 0.0:
        raise TrajectoryError("biarc: tangents pointing away from the chord")
    d = vv / root
    if not (math.isfinite(d) and d > 0.0):
        raise TrajectoryError(f"biarc: no joint (d = {d!r})")
    joint = 0.5 * ((p0 + d * t0) + (p1 - d * t1))
    first = arc_to(p0, t0, joint)
    tm = _end_tangent(first)
    second = arc_to(first.end, tm, p1)
    return first, second


def _end_tangent(seg: Segment) -> np.ndarray:
    return np.array(seg.unit_tangent(seg.length))


def spline_points(start: np.ndarray, through: np.ndarray) -> tuple[np.ndarray, object]:
    """The chord-length knots and the cubic spline through ``start`` and ``through``.

    Args:
        start: First point, shape (3,), m.
        through: The following points, shape (k, 3), m, k >= 1.

    Returns:
        ``(knots, spline)``: knots shape (k + 1,), m; ``spline(u)`` -> (…, 3) and
        ``spline(u, 1)`` its derivative.

    Raises:
        TrajectoryError: two consecutive points that coincide.
    """
    from scipy.interpolate import CubicSpline

    pts = np.vstack([start[None, :], through])
    chords = np.linalg.norm(np.diff(pts, axis=0), axis=1)
    if np.any(chords < MIN_LENGTH):
        k = int(np.argmin(chords))
        raise TrajectoryError(f"spline: points {k} and {k + 1} coincide")
    knots = np.concatenate([[0.0], np.cumsum(chords)])
    if len(pts) == 2:
        return knots, CubicSpline(knots, pts, bc_type="clamped")
    return knots, CubicSpline(knots, pts, bc_type="natural")


def fit_spline(
    start: np.ndarray, through: Sequence[Sequence[float]] | np.ndarray, tolerance: float
) -> list[Segment]:
    """Lines and arcs within ``tolerance`` of the cubic spline from ``start`` through points.

    Args:
        start: The leg's start, shape (3,), m.
        through: The points the curve passes, in order, shape (k, 3), m; the last is the end.
        tolerance: Largest distance (m) of the fit from the spline at the sampled points.

    Returns:
        Segments end to start, tangent-continuous, the first at ``start``.

    Raises:
        TrajectoryError: coinciding points, or a piece not fitted within ``tolerance`` after
            :data:`MAX_DEPTH` halvings.
    """
    pts = np.asarray(through, dtype=np.float64).reshape(-1, 3)
    knots, spline = spline_points(np.asarray(start, float), pts)
    segments: list[Segment] = []
    cursor = np.asarray(start, dtype=np.float64)
    for k in range(len(knots) - 1):
        cursor = _fit_piece(spline, knots[k], knots[k + 1], cursor, tolerance, 0, segments)
    return segments


def _unit(v: np.ndarray) -> np.ndarray:
    n = float(np.linalg.norm(v))
    if n < 1e-12:
        raise TrajectoryError("spline: zero tangent")
    return np.asarray(v / n, dtype=np.float64)


def _fit_piece(
    spline: object,
    u0: float,
    u1: float,
    cursor: np.ndarray,
    tol: float,
    depth: int,
    out: list[Segment],
) -> np.ndarray:
    """Append the biarc(s) of the spline on ``[u0, u1]`` starting at ``cursor``; return the end."""
    f = spline  # CubicSpline: f(u) point, f(u, 1) derivative
    p1 = np.asarray(f(u1), dtype=np.float64)  # type: ignore[operator]
    t0 = _unit(np.asarray(f(u0, 1)))  # type: ignore[operator]
    t1 = _unit(np.asarray(f(u1, 1)))  # type: ignore[operator]
    first, second = biarc(cursor, t0, p1, t1)
    samples = np.asarray(f(np.linspace(u0, u1, SAMPLES_PER_PIECE)))  # type: ignore[operator]
    err = max(_distance(samples, first, second))
    if err <= tol:
        out.extend((first, second))
        return np.array(second.end, dtype=np.float64)
    if depth >= MAX_DEPTH:
        raise TrajectoryError(
            f"spline: not within {tol:.3g} m with lines and arcs ({err:.3g} m after "
            f"{MAX_DEPTH} halvings)"
        )
    mid = 0.5 * (u0 + u1)
    cursor = _fit_piece(spline, u0, mid, cursor, tol, depth + 1, out)
    return _fit_piece(spline, mid, u1, cursor, tol, depth + 1, out)


def _distance(samples: np.ndarray, *segments: Segment) -> list[float]:
    """Each sample's distance (m) to the nearest of ``segments``."""
    out = []
    for x in samples.tolist():
        best = math.inf
        for seg in segments:
            p = seg.point(seg.project(*x))
            best = min(best, math.dist(x, p))
        out.append(best)
    return out
