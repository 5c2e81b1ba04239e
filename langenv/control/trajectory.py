"""Exercise trajectories: lines and arcs, arc-length parametrised, with stops.

A :class:`Trajectory` is the directed curve ``T`` of SPEC §1 (hand position in the robot base
frame, metres), built from :class:`LineSegment` and :class:`ArcSegment` pieces joined end to start.
It is parametrised by arc length ``s`` in ``[0, L]`` (the paper's ``d`` is ``s / L``). Segments
flagged ``stop=True`` make the hand come to rest at their end; the end of the trajectory is always
a stop. :meth:`Trajectory.closest` finds the closest point *locally*, by descent from the previous
closest point and inside a window ``[s_lo, s_hi]``: the default exercise returns over its own path,
so a global argmin would jump between its outbound and return legs.

The hot-path helpers (names starting with an underscore) work on plain Python floats: the guide
calls them 500 times a second and a small NumPy call costs about a microsecond.
"""

from __future__ import annotations

import math
from bisect import bisect_left, bisect_right
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike

from langenv.errors import TrajectoryError
from langenv.validation import as_vec3

__all__ = [
    "ArcSegment",
    "LineSegment",
    "Segment",
    "Trajectory",
    "default_exercise",
    "line",
]

#: Shortest segment (m) and smallest arc radius (m) accepted; below, a segment is degenerate.
MIN_LENGTH = 1e-6
#: Largest gap (m) between the end of a segment and the start of the next.
CONTINUITY_TOL = 1e-6

Vec3 = tuple[float, float, float]


def _as_vec3(value: ArrayLike, name: str) -> np.ndarray:
    """Return ``value`` as a read-only float64 array of shape (3,), or raise naming ``name``."""
    arr = np.array(as_vec3(value, name, TrajectoryError))  # a copy: the segment owns it
    arr.setflags(write=False)
    return arr


def _vec3(arr: np.ndarray) -> Vec3:
    return (float(arr[0]), float(arr[1]), float(arr[2]))


@dataclass(frozen=True, eq=False)
class LineSegment:
    """A straight segment from ``start`` to ``end``.

    Args:
        start: Start point, shape (3,), m.
        end: End point, shape (3,), m.
        stop: Whether the hand comes to rest at ``end``.

    Raises:
        TrajectoryError: a non-finite or badly shaped point, or ``start == end`` (zero length).
    """

    start: np.ndarray
    end: np.ndarray
    stop: bool = False
    length: float = field(init=False)
    _p0: Vec3 = field(init=False, repr=False)
    _u: Vec3 = field(init=False, repr=False)

    def __post_init__(self) -> None:
        start = _as_vec3(self.start, "LineSegment.start")
        end = _as_vec3(self.end, "LineSegment.end")
        length = float(np.linalg.norm(end - start))
        if length < MIN_LENGTH:
            raise TrajectoryError(
                f"LineSegment.end must differ from LineSegment.start (zero length segment at "
                f"{start.tolist()})"
            )
        object.__setattr__(self, "start", start)
        object.__setattr__(self, "end", end)
        object.__setattr__(self, "stop", bool(self.stop))
        object.__setattr__(self, "length", length)
        object.__setattr__(self, "_p0", _vec3(start))
        object.__setattr__(self, "_u", _vec3((end - start) / length))

    # --- plain-float kernels (local parameter t in [0, length]) -----------------------------
    def _point(self, t: float) -> Vec3:
        p, u = self._p0, self._u
        return (p[0] + t * u[0], p[1] + t * u[1], p[2] + t * u[2])

    def _tangent(self, t: float) -> Vec3:
        return self._u

    def _curvature(self, t: float) -> Vec3:
        return (0.0, 0.0, 0.0)

    def _frame(self, t: float) -> tuple[Vec3, Vec3, Vec3 | None]:
        """Point, unit tangent and curvature vector (``None`` on a line) at ``t``."""
        p, u = self._p0, self._u
        return (p[0] + t * u[0], p[1] + t * u[1], p[2] + t * u[2]), u, None

    def _project(self, x0: float, x1: float, x2: float) -> float:
        p, u = self._p0, self._u
        t = (x0 - p[0]) * u[0] + (x1 - p[1]) * u[1] + (x2 - p[2]) * u[2]
        return 0.0 if t < 0.0 else (self.length if t > self.length else t)


@dataclass(frozen=True, eq=False)
class ArcSegment:
    """A circular arc: ``start`` rotated by ``angle`` about the axis through ``center``.

    The rotation is right-handed about ``axis`` (a positive ``angle`` turns counter-clockwise when
    seen from the tip of ``axis``). ``center`` is any point of the rotation axis; the radius is the
    distance from ``start`` to that axis and the component of ``start - center`` along the axis is
    kept (the arc lies in the plane through ``start`` perpendicular to the axis).

    Args:
        center: A point on the rotation axis, shape (3,), m.
        axis: Rotation axis direction, shape (3,) (normalised here).
        start: Start point, shape (3,), m; must not lie on the axis.
        angle: Signed rotation angle (rad), ``0 < |angle| <= 2 pi``.
        stop: Whether the hand comes to rest at the end of the arc.

    Raises:
        TrajectoryError: a non-finite or badly shaped vector, a zero axis, ``start`` on the axis,
            or a zero / non-finite / more than one-turn angle.
    """

    center: np.ndarray
    axis: np.ndarray
    start: np.ndarray
    angle: float
    stop: bool = False
    radius: float = field(init=False)
    length: float = field(init=False)
    end: np.ndarray = field(init=False)
    _c: Vec3 = field(init=False, repr=False)
    _a: Vec3 = field(init=False, repr=False)
    _e1: Vec3 = field(init=False, repr=False)
    _e2: Vec3 = field(init=False, repr=False)
    _sign: float = field(init=False, repr=False)

    def __post_init__(self) -> None:
        center = _as_vec3(self.center, "ArcSegment.center")
        axis = _as_vec3(self.axis, "ArcSegment.axis")
        start = _as_vec3(self.start, "ArcSegment.start")
        try:
            angle = float(self.angle)
        except (TypeError, ValueError) as exc:
            raise TrajectoryError(f"ArcSegment.angle must be a number, got {self.angle!r}") from exc
        axis_norm = float(np.linalg.norm(axis))
        if axis_norm < 1e-12:
            raise TrajectoryError("ArcSegment.axis must be non-zero, got [0, 0, 0]")
        if not math.isfinite(angle) or abs(angle) < 1e-12 or abs(angle) > 2.0 * math.pi + 1e-12:
            raise TrajectoryError(
                f"ArcSegment.angle must be finite with 0 < |angle| <= 2 pi rad, got {angle!r}"
            )
        a = axis / axis_norm
        rel = start - center
        axial = float(rel @ a)
        radial = rel - axial * a
        radius = float(np.linalg.norm(radial))
        if radius < MIN_LENGTH:
            raise TrajectoryError(
                f"ArcSegment.start {start.tolist()} lies on the rotation axis "
                f"(radius {radius:.3g} m)"
            )
        e1 = radial / radius
        e2 = np.cross(a, e1)
        sign = 1.0 if angle > 0.0 else -1.0
        c_plane = center + axial * a
        end = c_plane + radius * (math.cos(angle) * e1 + math.sin(angle) * e2)
        end.setflags(write=False)
        a.setflags(write=False)
        object.__setattr__(self, "center", center)
        object.__setattr__(self, "axis", a)
        object.__setattr__(self, "start", start)
        object.__setattr__(self, "angle", angle)
        object.__setattr__(self, "stop", bool(self.stop))
        object.__setattr__(self, "radius", radius)
        object.__setattr__(self, "length", radius * abs(angle))
        object.__setattr__(self, "end", end)
        object.__setattr__(self, "_c", _vec3(c_plane))
        object.__setattr__(self, "_a", _vec3(a))
        object.__setattr__(self, "_e1", _vec3(e1))
        object.__setattr__(self, "_e2", _vec3(e2))
        object.__setattr__(self, "_sign", sign)

    # --- plain-float kernels (local parameter t in [0, length]) -----------------------------
    def _point(self, t: float) -> Vec3:
        th = self._sign * t / self.radius
        cr, sr = self.radius * math.cos(th), self.radius * math.sin(th)
        c, e1, e2 = self._c, self._e1, self._e2
        return (
            c[0] + cr * e1[0] + sr * e2[0],
            c[1] + cr * e1[1] + sr * e2[1],
            c[2] + cr * e1[2] + sr * e2[2],
        )

    def _tangent(self, t: float) -> Vec3:
        th = self._sign * t / self.radius
        cs, sn = self._sign * math.cos(th), self._sign * math.sin(th)
        e1, e2 = self._e1, self._e2
        return (-sn * e1[0] + cs * e2[0], -sn * e1[1] + cs * e2[1], -sn * e1[2] + cs * e2[2])

    def _curvature(self, t: float) -> Vec3:
        th = self._sign * t / self.radius
        k = 1.0 / self.radius
        cs, sn = -k * math.cos(th), -k * math.sin(th)
        e1, e2 = self._e1, self._e2
        return (cs * e1[0] + sn * e2[0], cs * e1[1] + sn * e2[1], cs * e1[2] + sn * e2[2])

    def _frame(self, t: float) -> tuple[Vec3, Vec3, Vec3 | None]:
        """Point, unit tangent and curvature vector at ``t`` (one cos/sin)."""
        th = self._sign * t / self.radius
        cs, sn = math.cos(th), math.sin(th)
        r, sg, k = self.radius, self._sign, 1.0 / self.radius
        c, e1, e2 = self._c, self._e1, self._e2
        r0 = cs * e1[0] + sn * e2[0]
        r1 = cs * e1[1] + sn * e2[1]
        r2 = cs * e1[2] + sn * e2[2]
        return (
            (c[0] + r * r0, c[1] + r * r1, c[2] + r * r2),
            (
                sg * (-sn * e1[0] + cs * e2[0]),
                sg * (-sn * e1[1] + cs * e2[1]),
                sg * (-sn * e1[2] + cs * e2[2]),
            ),
            (-k * r0, -k * r1, -k * r2),
        )

    def _project(self, x0: float, x1: float, x2: float) -> float:
        c, e1, e2 = self._c, self._e1, self._e2
        d0, d1, d2 = x0 - c[0], x1 - c[1], x2 - c[2]
        u1 = d0 * e1[0] + d1 * e1[1] + d2 * e1[2]
        u2 = d0 * e2[0] + d1 * e2[1] + d2 * e2[2]
        if u1 == 0.0 and u2 == 0.0:
            return 0.0  # on the axis: every point of the arc is equally close
        phi = math.atan2(self._sign * u2, u1)  # angle travelled, in (-pi, pi]
        if phi < 0.0:
            phi += 2.0 * math.pi  # [0, 2 pi)
        span = abs(self.angle)
        if phi > span:  # outside the arc: the nearer end (in angle) is the closer point
            phi = span if phi - span < 2.0 * math.pi - phi else 0.0
        return phi * self.radius


Segment = LineSegment | ArcSegment


def _segment_end(seg: Segment) -> np.ndarray:
    return seg.end


class Trajectory:
    """A directed curve made of segments, parametrised by arc length.

    Args:
        segments: The pieces, in order; each must start where the previous one ends (within
            ``CONTINUITY_TOL``). The end of the last segment is always a stop.

    Attributes:
        segments: The segments, as a tuple.
        length: Total arc length ``L`` (m).
        seg_start: Arc length at the start of each segment, shape (n,), m.
        seg_end: Arc length at the end of each segment, shape (n,), m.
        stop_s: Arc lengths of the stops, ascending, shape (k,), last ``== length``, m.

    Raises:
        TrajectoryError: no segments, a segment of the wrong type, or a gap between segments.
    """

    def __init__(self, segments: Sequence[Segment]) -> None:
        segs = tuple(segments)
        if not segs:
            raise TrajectoryError("Trajectory.segments must contain at least one segment")
        for i, seg in enumerate(segs):
            if not isinstance(seg, LineSegment | ArcSegment):
                raise TrajectoryError(
                    f"Trajectory.segments[{i}] must be a LineSegment or ArcSegment, "
                    f"got {type(seg).__name__}"
                )
            if i > 0:
                gap = float(np.linalg.norm(seg.start - _segment_end(segs[i - 1])))
                if gap > CONTINUITY_TOL:
                    raise TrajectoryError(
                        f"Trajectory.segments[{i}].start is {gap:.3g} m away from the end of "
                        f"segments[{i - 1}] (discontinuous trajectory)"
                    )
        self.segments: tuple[Segment, ...] = segs
        lengths = np.array([seg.length for seg in segs])
        ends = np.cumsum(lengths)
        self.seg_end: np.ndarray = ends
        self.seg_start: np.ndarray = ends - lengths
        self.length: float = float(ends[-1])
        stops = [float(e) for seg, e in zip(segs, ends, strict=True) if seg.stop]
        if not stops or stops[-1] < self.length:
            stops.append(self.length)
        stops[-1] = self.length
        self.stop_s: np.ndarray = np.array(stops)
        for arr in (self.seg_end, self.seg_start, self.stop_s):
            arr.setflags(write=False)
        # plain-float copies for the hot path
        self._starts: list[float] = [float(v) for v in self.seg_start]
        self._ends: list[float] = [float(v) for v in ends]
        self._n = len(segs)

    def __repr__(self) -> str:
        kinds = ", ".join(type(s).__name__ for s in self.segments)
        return f"Trajectory([{kinds}], length={self.length:.4f} m, stops={self.stop_s.tolist()})"

    # ------------------------------------------------------------------ lookup
    def segment_index(self, s: float, side: str = "right") -> int:
        """Index of the segment containing arc length ``s``.

        Args:
            s: Arc length (m); clamped to ``[0, L]``.
            side: At a joint between two segments, ``"right"`` picks the one that starts there
                (the right derivative's segment), ``"left"`` the one that ends there.

        Returns:
            The segment index in ``[0, n)``.
        """
        if side == "right":
            i = bisect_right(self._starts, s) - 1
        elif side == "left":
            i = bisect_left(self._ends, s)
        else:
            raise TrajectoryError(f"segment_index: side must be 'left' or 'right', got {side!r}")
        return 0 if i < 0 else (self._n - 1 if i >= self._n else i)

    def _local(self, s: float, side_left: bool = False) -> tuple[Segment, float]:
        if side_left:
            i = bisect_left(self._ends, s)
        else:
            i = bisect_right(self._starts, s) - 1
        i = 0 if i < 0 else (self._n - 1 if i >= self._n else i)
        seg = self.segments[i]
        t = s - self._starts[i]
        return seg, (0.0 if t < 0.0 else (seg.length if t > seg.length else t))

    @staticmethod
    def _check_s(s: float) -> float:
        s = float(s)
        if not math.isfinite(s):
            raise TrajectoryError(f"arc length s must be finite, got {s!r}")
        return s

    # ------------------------------------------------------------------ geometry
    def position(self, s: float) -> np.ndarray:
        """Point ``T`` at arc length ``s``.

        Args:
            s: Arc length (m), clamped to ``[0, L]``.

        Returns:
            Position, shape (3,), m.
        """
        seg, t = self._local(self._check_s(s))
        return np.array(seg._point(t))

    def tangent(self, s: float) -> np.ndarray:
        """Unit tangent at ``s``: the right derivative ``dT/ds`` (at a joint: the next segment).

        Args:
            s: Arc length (m), clamped to ``[0, L]``.

        Returns:
            Unit vector, shape (3,).
        """
        seg, t = self._local(self._check_s(s))
        return np.array(seg._tangent(t))

    def curvature(self, s: float) -> np.ndarray:
        """Curvature vector ``d^2T/ds^2 = kappa n`` at ``s`` (right-sided), 0 on lines.

        Args:
            s: Arc length (m), clamped to ``[0, L]``.

        Returns:
            Vector pointing to the centre of curvature, norm ``1 / radius``, shape (3,), 1/m.
        """
        seg, t = self._local(self._check_s(s))
        return np.array(seg._curvature(t))

    def sample(self, n: int = 200) -> np.ndarray:
        """Points at ``n`` equally spaced arc lengths from 0 to ``L`` (for plots).

        Args:
            n: Number of points, >= 2.

        Returns:
            Positions, shape (n, 3), m.
        """
        if int(n) < 2:
            raise TrajectoryError(f"sample: n must be >= 2, got {n!r}")
        out = np.empty((int(n), 3))
        for k, s in enumerate(np.linspace(0.0, self.length, int(n))):
            seg, t = self._local(float(s))
            out[k] = seg._point(t)
        return out

    # ------------------------------------------------------------------ closest point
    def closest(
        self, x: np.ndarray, s_prev: float, s_lo: float = 0.0, s_hi: float | None = None
    ) -> float:
        """Closest point of the curve to ``x``, searched locally around ``s_prev``.

        Starting from the segment containing ``s_prev``, the point is projected on that segment;
        while the projection sits at an end of the segment and the neighbouring segment (inside
        ``[s_lo, s_hi]``) is strictly closer, the search moves on to it. So the result is the
        local minimum of the distance reached by descent from ``s_prev``: it never jumps to a
        distant part of the curve that happens to pass near ``x`` (a return leg).

        Args:
            x: Hand position, shape (3,), m.
            s_prev: Previous closest point (m).
            s_lo: Lower end of the search window (m).
            s_hi: Upper end of the search window (m); ``None`` means ``L``.

        Returns:
            Arc length of the closest point, in ``[s_lo, s_hi]`` (m).

        Raises:
            TrajectoryError: a non-finite input or an empty window.
        """
        xa = np.asarray(x, dtype=np.float64)
        if xa.shape != (3,) or not np.all(np.isfinite(xa)):
            raise TrajectoryError(f"closest: x must be a finite 3-vector, got {x!r}")
        hi = self.length if s_hi is None else self._check_s(s_hi)
        lo = self._check_s(s_lo)
        if lo > hi:
            raise TrajectoryError(f"closest: window is empty (s_lo={lo} > s_hi={hi})")
        x0, x1, x2 = xa.tolist()
        return self._closest(x0, x1, x2, self._check_s(s_prev), lo, hi)

    def _dist2_on(
        self, i: int, x0: float, x1: float, x2: float, lo: float, hi: float
    ) -> tuple[float, float]:
        """Projection of x on segment ``i`` restricted to ``[lo, hi]``: (s, squared distance)."""
        seg = self.segments[i]
        s0 = self._starts[i]
        s = s0 + seg._project(x0, x1, x2)
        s = lo if s < lo else (hi if s > hi else s)
        p = seg._point(s - s0)
        d0, d1, d2 = x0 - p[0], x1 - p[1], x2 - p[2]
        return s, d0 * d0 + d1 * d1 + d2 * d2

    def _closest(
        self, x0: float, x1: float, x2: float, s_prev: float, lo: float, hi: float
    ) -> float:
        s_prev = lo if s_prev < lo else (hi if s_prev > hi else s_prev)
        i = bisect_right(self._starts, s_prev) - 1
        n = self._n
        i = 0 if i < 0 else (n - 1 if i >= n else i)
        best_s, best_d2 = self._dist2_on(i, x0, x1, x2, lo, hi)
        eps = 1e-12
        if i > 0 and s_prev <= self._starts[i] + eps and self._starts[i] > lo:
            # s_prev on a joint belongs to both segments: start from the closer one
            s, d2 = self._dist2_on(i - 1, x0, x1, x2, lo, hi)
            if d2 < best_d2:
                best_s, best_d2, i = s, d2, i - 1
        j = i
        moved = False
        # descend forward while the projection sits at the segment's end
        while j + 1 < n and best_s >= self._ends[j] - eps and self._ends[j] < hi:
            s, d2 = self._dist2_on(j + 1, x0, x1, x2, lo, hi)
            if d2 < best_d2 - eps * eps:
                best_s, best_d2 = s, d2
                j += 1
                moved = True
            else:
                break
        if not moved:
            j = i
            while j > 0 and best_s <= self._starts[j] + eps and self._starts[j] > lo:
                s, d2 = self._dist2_on(j - 1, x0, x1, x2, lo, hi)
                if d2 < best_d2 - eps * eps:
                    best_s, best_d2 = s, d2
                    j -= 1
                else:
                    break
        return best_s


def line(
    start: Sequence[float] | np.ndarray, end: Sequence[float] | np.ndarray, stop: bool = True
) -> Trajectory:
    """A one-segment straight trajectory (for tests and simple exercises).

    Args:
        start: Start point, shape (3,), m.
        end: End point, shape (3,), m.
        stop: Kept for symmetry; the end of a trajectory is always a stop.

    Returns:
        The trajectory.
    """
    return Trajectory([LineSegment(np.asarray(start, float), np.asarray(end, float), stop=stop)])


#: SPEC §2 "shoulder external rotation": start point (m, robot base frame).
EXERCISE_START = (-0.350, -0.6206, 0.04)
#: A point on the vertical axis the forearm rotates about (m).
EXERCISE_PIVOT = (-0.400, -0.256, 0.0)
#: Rotation of the outbound arc (rad): +40 deg, counter-clockwise seen from above.
EXERCISE_ANGLE = math.radians(40.0)


def default_exercise() -> Trajectory:
    """The study's exercise, "shoulder external rotation" (SPEC §2).

    The hand starts at ``(-0.350, -0.6206, 0.04)`` m, turns 40 deg about the vertical axis through
    ``(-0.400, -0.256, 0)`` (radius 0.368 m, arc 0.257 m), goes straight back to the start
    (chord 0.252 m) and turns out again along the same arc; it comes to rest at the end of each of
    the three segments. Total length 0.766 m.

    Rotation sense: +40 deg, right-handed about +z (counter-clockwise seen from above), so the hand
    moves towards +x, to about ``(-0.128, -0.503, 0.04)``. The SPEC fixes the pivot and the start
    but not the sense; we read "away from the body" as follows. The forearm points from the elbow
    (on the pivot axis) along -y, so the person faces -y and the torso lies beside the elbow along
    x. It cannot lie on the +x side: the robot's base (the origin) is there, 0.4 m from the elbow.
    So the torso is on the -x side and external rotation swings the hand to +x. The same sense
    keeps the hand inside the UR5's reach (0.52 m from the base at the arc's end, against 0.82 m
    for the opposite sense, at the edge of its 0.85 m reach).

    Returns:
        The trajectory (arc, line, arc), with stops at 0.257, 0.509 and 0.766 m.
    """
    start = np.array(EXERCISE_START)
    pivot = np.array(EXERCISE_PIVOT)
    up = np.array([0.0, 0.0, 1.0])
    out = ArcSegment(center=pivot, axis=up, start=start, angle=EXERCISE_ANGLE, stop=True)
    back = LineSegment(start=out.end, end=start, stop=True)
    again = ArcSegment(center=pivot, axis=up, start=start, angle=EXERCISE_ANGLE, stop=True)
    return Trajectory([out, back, again])
