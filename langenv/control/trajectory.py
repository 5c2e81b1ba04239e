"""Exercise trajectories: lines and arcs, arc-length parametrised, in legs between waypoints.

A :class:`Trajectory` is the directed curve ``T`` of SPEC §1 (hand position in the robot base
frame, metres), built from :class:`LineSegment` and :class:`ArcSegment` pieces joined end to start.
It is parametrised by arc length ``s`` in ``[0, L]`` (the paper's ``d`` is ``s / L``). The end of a
segment flagged ``waypoint=True`` ends a *leg* of the exercise (the lab code's "segment"): the
guide drives the hand along one leg at a time and moves on to the next when the hand comes close
to the leg's end pose (:mod:`langenv.control.guide`); the end of the trajectory always ends the
last leg. Each segment also carries the tool's ``turn`` (rad): how far the handle would turn over
it if it followed the exercise (it does on an arc, and back along the line in the study), used in
the lab's 6-D closeness test; :meth:`Trajectory.tool_angle` is its running total along the path.
:meth:`Trajectory.closest` finds the closest point *locally*, by descent from the previous
closest point and inside a window ``[s_lo, s_hi]``: the default exercise returns over its own path,
so a global argmin would jump between its outbound and return legs. An arc of more than half a turn
(a circle, a lobe) is kept as equal pieces of at most :data:`MAX_ARC_ANGLE` (:func:`split_arc`):
an arc's projection picks, for a point beside its gap, the end nearer in angle, so on one piece
of a full circle a hand just behind its start would project to its end, and one just past its
end to its start; on pieces of at most half a turn the descent moves from piece to piece.

The hot-path methods (:meth:`Trajectory.locate`, :meth:`Trajectory.closest_xyz`, the segments'
``point``, ``unit_tangent``, ``frame`` and ``project``) work on plain Python floats and check
nothing: the guide calls them 500 times a second and a small NumPy call costs about a microsecond.
"""

from __future__ import annotations

import math
from bisect import bisect_left, bisect_right
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike

from langenv import vec
from langenv.errors import TrajectoryError
from langenv.layout import Layout, field_table
from langenv.validation import as_vec3

__all__ = [
    "SEGMENT",
    "ArcSegment",
    "LineSegment",
    "Segment",
    "Trajectory",
    "default_exercise",
    "line",
    "split_arc",
]

#: Shortest segment (m) and smallest arc radius (m) accepted; below, a segment is degenerate.
MIN_LENGTH = 1e-6
#: Largest gap (m) between the end of a segment and the start of the next.
CONTINUITY_TOL = 1e-6
#: Largest angle (rad) of one arc segment of a :class:`Trajectory`: longer arcs are split.
MAX_ARC_ANGLE = math.pi

Vec3 = tuple[float, float, float]

SEGMENT = Layout(
    "segment",
    field_table(
        """
        kind:int   0 a line, 1 an arc
        s0         arc length at the segment's start (m)
        s1         arc length at its end (m)
        length     its length (m)
        turn0      the tool's running turn at its start (rad)
        turn_rate  the tool's turn per metre along it (rad/m)
        origin[3]  a line's start point, an arc's centre (m)
        axis1[3]   a line's unit direction, an arc's e1 (start radius direction)
        axis2[3]   an arc's e2 (in-plane normal to e1; zeros for a line)
        radius     an arc's radius (m)
        sign       an arc's sense of rotation about its axis (+-1)
        angle      an arc's swept angle (rad)
        """
    ),
)
"""One row of a packed trajectory (:meth:`Trajectory.packed`): what the compiled path functions
(:mod:`langenv.control.trajectory_kernels`) read."""


def _as_vec3(value: ArrayLike, name: str) -> np.ndarray:
    """Return ``value`` as a read-only float64 array of shape (3,), or raise naming ``name``."""
    arr = np.array(as_vec3(value, name, TrajectoryError))  # a copy: the segment owns it
    arr.setflags(write=False)
    return arr


def _vec3(arr: np.ndarray) -> Vec3:
    return (float(arr[0]), float(arr[1]), float(arr[2]))


def _check_turn(value: object, name: str) -> float:
    """``value`` as a finite float >= 0 (a tool rotation in rad), or raise naming ``name``."""
    try:
        turn = float(value)  # type: ignore[arg-type]
    except (TypeError, ValueError) as exc:
        raise TrajectoryError(f"{name} must be a number of radians, got {value!r}") from exc
    if isinstance(value, bool) or not (math.isfinite(turn) and turn >= 0.0):
        raise TrajectoryError(f"{name} must be finite and >= 0 rad, got {value!r}")
    return turn


@dataclass(frozen=True, eq=False)
class LineSegment:
    """A straight segment from ``start`` to ``end``.

    Args:
        start: Start point, shape (3,), m.
        end: End point, shape (3,), m.
        waypoint: Whether ``end`` ends a leg of the exercise (see the module docstring).
        turn: Tool rotation over the segment (rad, >= 0), linear in arc length.

    Raises:
        TrajectoryError: a non-finite or badly shaped point, ``start == end`` (zero length), or
            a negative or non-finite ``turn``.
    """

    start: np.ndarray
    end: np.ndarray
    waypoint: bool = False
    turn: float = 0.0
    length: float = field(init=False)
    _p0: Vec3 = field(init=False, repr=False)
    _u: Vec3 = field(init=False, repr=False)

    def __post_init__(self) -> None:
        start = _as_vec3(self.start, "LineSegment.start")
        end = _as_vec3(self.end, "LineSegment.end")
        length = vec.norm(end - start)
        if length < MIN_LENGTH:
            raise TrajectoryError(
                f"LineSegment.end must differ from LineSegment.start (zero length segment at "
                f"{start.tolist()})"
            )
        object.__setattr__(self, "start", start)
        object.__setattr__(self, "end", end)
        object.__setattr__(self, "waypoint", bool(self.waypoint))
        object.__setattr__(self, "turn", _check_turn(self.turn, "LineSegment.turn"))
        object.__setattr__(self, "length", length)
        object.__setattr__(self, "_p0", _vec3(start))
        object.__setattr__(self, "_u", _vec3((end - start) / length))

    # --- plain-float kernels (local parameter t in [0, length], unchecked) ------------------
    def point(self, t: float) -> Vec3:
        """Point at local arc length ``t`` (m)."""
        p, u = self._p0, self._u
        return (p[0] + t * u[0], p[1] + t * u[1], p[2] + t * u[2])

    def unit_tangent(self, t: float) -> Vec3:
        """Unit tangent (direction of travel) at ``t``."""
        return self._u

    def curvature_at(self, t: float) -> Vec3:
        """Curvature vector at ``t`` (1/m): zero on a line."""
        return (0.0, 0.0, 0.0)

    def frame(self, t: float) -> tuple[Vec3, Vec3, Vec3 | None]:
        """Point, unit tangent and curvature vector (``None`` on a line) at ``t``."""
        p, u = self._p0, self._u
        return (p[0] + t * u[0], p[1] + t * u[1], p[2] + t * u[2]), u, None

    def project(self, x0: float, x1: float, x2: float) -> float:
        """Local arc length of the point of the segment closest to ``(x0, x1, x2)`` (m)."""
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
        waypoint: Whether the end of the arc ends a leg of the exercise (module docstring).
        turn: Tool rotation over the arc (rad, >= 0); ``None``: ``|angle|`` (the tool turns
            with the arc).

    Raises:
        TrajectoryError: a non-finite or badly shaped vector, a zero axis, ``start`` on the axis,
            a zero / non-finite / more than one-turn angle, or a negative or non-finite ``turn``.
    """

    center: np.ndarray
    axis: np.ndarray
    start: np.ndarray
    angle: float
    waypoint: bool = False
    turn: float | None = None
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
        axis_norm = vec.norm(axis)
        if axis_norm < 1e-12:
            raise TrajectoryError("ArcSegment.axis must be non-zero, got [0, 0, 0]")
        if not math.isfinite(angle) or abs(angle) < 1e-12 or abs(angle) > 2.0 * math.pi + 1e-12:
            raise TrajectoryError(
                f"ArcSegment.angle must be finite with 0 < |angle| <= 2 pi rad, got {angle!r}"
            )
        a = axis / axis_norm
        rel = start - center
        axial = vec.dot(rel, a)
        radial = rel - axial * a
        radius = vec.norm(radial)
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
        object.__setattr__(self, "waypoint", bool(self.waypoint))
        turn = abs(angle) if self.turn is None else _check_turn(self.turn, "ArcSegment.turn")
        object.__setattr__(self, "turn", turn)
        object.__setattr__(self, "radius", radius)
        object.__setattr__(self, "length", radius * abs(angle))
        object.__setattr__(self, "end", end)
        object.__setattr__(self, "_c", _vec3(c_plane))
        object.__setattr__(self, "_a", _vec3(a))
        object.__setattr__(self, "_e1", _vec3(e1))
        object.__setattr__(self, "_e2", _vec3(e2))
        object.__setattr__(self, "_sign", sign)

    # --- plain-float kernels (local parameter t in [0, length], unchecked) ------------------
    def point(self, t: float) -> Vec3:
        """Point at local arc length ``t`` (m)."""
        th = self._sign * t / self.radius
        cr, sr = self.radius * math.cos(th), self.radius * math.sin(th)
        c, e1, e2 = self._c, self._e1, self._e2
        return (
            c[0] + cr * e1[0] + sr * e2[0],
            c[1] + cr * e1[1] + sr * e2[1],
            c[2] + cr * e1[2] + sr * e2[2],
        )

    def unit_tangent(self, t: float) -> Vec3:
        """Unit tangent (direction of travel) at ``t``."""
        th = self._sign * t / self.radius
        cs, sn = self._sign * math.cos(th), self._sign * math.sin(th)
        e1, e2 = self._e1, self._e2
        return (-sn * e1[0] + cs * e2[0], -sn * e1[1] + cs * e2[1], -sn * e1[2] + cs * e2[2])

    def curvature_at(self, t: float) -> Vec3:
        """Curvature vector at ``t`` (1/m): towards the centre, norm ``1 / radius``."""
        th = self._sign * t / self.radius
        k = 1.0 / self.radius
        cs, sn = -k * math.cos(th), -k * math.sin(th)
        e1, e2 = self._e1, self._e2
        return (cs * e1[0] + sn * e2[0], cs * e1[1] + sn * e2[1], cs * e1[2] + sn * e2[2])

    def frame(self, t: float) -> tuple[Vec3, Vec3, Vec3 | None]:
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

    def project(self, x0: float, x1: float, x2: float) -> float:
        """Local arc length of the point of the arc closest to ``(x0, x1, x2)`` (m)."""
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


def split_arc(arc: ArcSegment) -> list[ArcSegment]:
    """``arc`` as equal arcs of at most :data:`MAX_ARC_ANGLE` each, end to start.

    An arc of at most half a turn is returned as it is. Longer ones (up to a full circle) become
    ``ceil(|angle| / pi)`` pieces, each with its share of the tool's turn; only the last keeps
    the ``waypoint`` flag. The pieces trace the same circle (their ends differ from the whole
    arc's by rounding only).

    Args:
        arc: The arc.

    Returns:
        The pieces, in order.
    """
    n = math.ceil(abs(arc.angle) / MAX_ARC_ANGLE - 1e-12)
    if n <= 1:
        return [arc]
    turn = float(arc.turn or 0.0) / n
    pieces: list[ArcSegment] = []
    start = arc.start
    for i in range(n):
        last = i == n - 1
        piece = ArcSegment(arc.center, arc.axis, start, arc.angle / n, arc.waypoint and last, turn)
        pieces.append(piece)
        start = piece.end
    return pieces


class Trajectory:
    """A directed curve made of segments, parametrised by arc length, in legs between waypoints.

    Args:
        segments: The pieces, in order; each must start where the previous one ends (within
            ``CONTINUITY_TOL``). The end of the last segment always ends the last leg. An arc
            of more than half a turn is kept as its :func:`split_arc` pieces.

    Attributes:
        segments: The segments, as a tuple.
        length: Total arc length ``L`` (m).
        seg_start: Arc length at the start of each segment, shape (n,), m.
        seg_end: Arc length at the end of each segment, shape (n,), m.
        waypoint_s: Arc lengths of the legs' ends, ascending, shape (k,), last ``== length``, m.

    Raises:
        TrajectoryError: no segments, a segment of the wrong type, or a gap between segments.
    """

    def __init__(self, segments: Sequence[Segment]) -> None:
        given = tuple(segments)
        if not given:
            raise TrajectoryError("Trajectory.segments must contain at least one segment")
        for i, seg in enumerate(given):
            if not isinstance(seg, LineSegment | ArcSegment):
                raise TrajectoryError(
                    f"Trajectory.segments[{i}] must be a LineSegment or ArcSegment, "
                    f"got {type(seg).__name__}"
                )
        segs: tuple[Segment, ...] = tuple(
            piece
            for seg in given
            for piece in (split_arc(seg) if isinstance(seg, ArcSegment) else (seg,))
        )
        for i, seg in enumerate(segs):
            if i > 0:
                gap = vec.norm(seg.start - segs[i - 1].end)
                if gap > CONTINUITY_TOL:
                    raise TrajectoryError(
                        f"Trajectory.segments[{i}].start is {gap:.3g} m away from the end of "
                        f"segments[{i - 1}] (discontinuous trajectory)"
                    )
        self.segments: tuple[Segment, ...] = segs
        lengths = np.array([seg.length for seg in segs])
        ends = np.cumsum(lengths)
        self.seg_end: np.ndarray = ends
        # each start is exactly the previous end: ``ends - lengths`` can differ from it by a
        # rounding error, and a joint's arc length would then fall in the arriving segment
        # (``locate`` and the packed path's ``S0`` column read these)
        self.seg_start: np.ndarray = np.concatenate([[0.0], ends[:-1]])
        self.length: float = float(ends[-1])
        waypoints = [float(e) for seg, e in zip(segs, ends, strict=True) if seg.waypoint]
        if not waypoints or waypoints[-1] < self.length:
            waypoints.append(self.length)
        waypoints[-1] = self.length
        self.waypoint_s: np.ndarray = np.array(waypoints)
        turns = np.array([float(seg.turn or 0.0) for seg in segs])  # arcs: resolved in init
        self._turn_start = np.concatenate([[0.0], np.cumsum(turns)[:-1]]).tolist()
        self._turn_rate = (turns / lengths).tolist()
        for arr in (self.seg_end, self.seg_start, self.waypoint_s):
            arr.setflags(write=False)
        # plain-float copies for the hot path
        self._starts: list[float] = [float(v) for v in self.seg_start]
        self._ends: list[float] = [float(v) for v in ends]
        self._n = len(segs)

    def __repr__(self) -> str:
        kinds = ", ".join(type(s).__name__ for s in self.segments)
        return (
            f"Trajectory([{kinds}], length={self.length:.4f} m, "
            f"waypoints={self.waypoint_s.tolist()})"
        )

    def fingerprint(self) -> tuple[object, ...]:
        """Hashable summary of the geometry (segments, waypoints, turns), equal for equal paths."""
        parts: list[object] = []
        for seg in self.segments:
            if isinstance(seg, ArcSegment):
                geo = (*seg.center.tolist(), *seg.axis.tolist(), *seg.start.tolist(), seg.angle)
            else:
                geo = (*seg.start.tolist(), *seg.end.tolist())
            parts.append((type(seg).__name__, geo, seg.waypoint, seg.turn))
        return tuple(parts)

    def packed(self) -> np.ndarray:
        """The segments as rows of :data:`SEGMENT`, shape ``(n, SEGMENT.size)``, float64: the
        trajectory as the compiled kernels take it."""
        rows = np.zeros((len(self.segments), SEGMENT.size))
        for i, seg in enumerate(self.segments):
            values: dict[str, object] = {
                "s0": self._starts[i],
                "s1": self._ends[i],
                "length": seg.length,
                "turn0": self._turn_start[i],
                "turn_rate": self._turn_rate[i],
            }
            if isinstance(seg, ArcSegment):
                values.update(
                    kind=1, origin=seg._c, axis1=seg._e1, axis2=seg._e2, radius=seg.radius,
                    sign=seg._sign, angle=seg.angle,
                )  # fmt: skip
            else:
                values.update(kind=0, origin=seg._p0, axis1=seg._u)
            SEGMENT.pack(rows[i], values)
        return rows

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

    def locate(self, s: float, arriving: bool = False) -> tuple[Segment, float]:
        """The segment containing arc length ``s`` and the local arc length on it (hot path).

        Args:
            s: Arc length (m), clamped to the trajectory; not checked.
            arriving: At a joint, the segment that ends there (default: the one that starts).

        Returns:
            ``(segment, t)`` with ``t`` in ``[0, segment.length]`` (m).
        """
        if arriving:
            i = bisect_left(self._ends, s)
        else:
            i = bisect_right(self._starts, s) - 1
        i = 0 if i < 0 else (self._n - 1 if i >= self._n else i)
        seg = self.segments[i]
        t = s - self._starts[i]
        return seg, (0.0 if t < 0.0 else (seg.length if t > seg.length else t))

    def tool_angle(self, s: float) -> float:
        """How far the tool has turned at arc length ``s`` (rad): the segments' ``turn`` summed.

        Args:
            s: Arc length (m), clamped to ``[0, L]``; not checked (hot path).

        Returns:
            The running total of the turn, non-decreasing in ``s`` (rad).
        """
        i = bisect_right(self._starts, s) - 1
        i = 0 if i < 0 else (self._n - 1 if i >= self._n else i)
        t = s - self._starts[i]
        seg_len = self._ends[i] - self._starts[i]
        t = 0.0 if t < 0.0 else (seg_len if t > seg_len else t)
        return self._turn_start[i] + self._turn_rate[i] * t

    def turn_rate(self, s: float, arriving: bool = False) -> float:
        """The tool's turn per metre of path at ``s`` (rad/m), on the side given by ``arriving``."""
        i = bisect_left(self._ends, s) if arriving else bisect_right(self._starts, s) - 1
        return self._turn_rate[0 if i < 0 else (self._n - 1 if i >= self._n else i)]

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
        seg, t = self.locate(self._check_s(s))
        return np.array(seg.point(t))

    def tangent(self, s: float) -> np.ndarray:
        """Unit tangent at ``s``: the right derivative ``dT/ds`` (at a joint: the next segment).

        Args:
            s: Arc length (m), clamped to ``[0, L]``.

        Returns:
            Unit vector, shape (3,).
        """
        seg, t = self.locate(self._check_s(s))
        return np.array(seg.unit_tangent(t))

    def curvature(self, s: float) -> np.ndarray:
        """Curvature vector ``d^2T/ds^2 = kappa n`` at ``s`` (right-sided), 0 on lines.

        Args:
            s: Arc length (m), clamped to ``[0, L]``.

        Returns:
            Vector pointing to the centre of curvature, norm ``1 / radius``, shape (3,), 1/m.
        """
        seg, t = self.locate(self._check_s(s))
        return np.array(seg.curvature_at(t))

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
            seg, t = self.locate(float(s))
            out[k] = seg.point(t)
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
        return self.closest_xyz(x0, x1, x2, self._check_s(s_prev), lo, hi)

    def _dist2_on(
        self, i: int, x0: float, x1: float, x2: float, lo: float, hi: float
    ) -> tuple[float, float]:
        """Projection of x on segment ``i`` restricted to ``[lo, hi]``: (s, squared distance)."""
        seg = self.segments[i]
        s0 = self._starts[i]
        s = s0 + seg.project(x0, x1, x2)
        s = lo if s < lo else (hi if s > hi else s)
        p = seg.point(s - s0)
        d0, d1, d2 = x0 - p[0], x1 - p[1], x2 - p[2]
        return s, d0 * d0 + d1 * d1 + d2 * d2

    def closest_xyz(
        self, x0: float, x1: float, x2: float, s_prev: float, lo: float, hi: float
    ) -> float:
        """:meth:`closest` on plain floats, without checks (the guide's hot path)."""
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


def line(start: Sequence[float] | np.ndarray, end: Sequence[float] | np.ndarray) -> Trajectory:
    """A one-segment straight trajectory, one leg (for tests and simple exercises).

    Args:
        start: Start point, shape (3,), m.
        end: End point, shape (3,), m.

    Returns:
        The trajectory.
    """
    return Trajectory([LineSegment(np.asarray(start, float), np.asarray(end, float), True)])


#: SPEC §2 "shoulder external rotation": start point (m, robot base frame).
EXERCISE_START = (-0.350, -0.6206, 0.04)
#: A point on the vertical axis the forearm rotates about (m).
EXERCISE_PIVOT = (-0.400, -0.256, 0.0)
#: Rotation of the outbound arc (deg), counter-clockwise seen from above: fitted to the recordings
#: (SPEC §2 "path length in the recordings"; the lab code's default was 40 deg).
EXERCISE_ANGLE_DEG = 43.0


def default_exercise(angle_deg: float = EXERCISE_ANGLE_DEG) -> Trajectory:
    """The study's exercise, "shoulder external rotation" (SPEC §2), in three legs.

    The hand starts at ``(-0.350, -0.6206, 0.04)`` m, turns ``angle_deg`` about the vertical axis
    through ``(-0.400, -0.256, 0)`` (radius 0.368 m), goes straight back to the start and turns out
    again along the same arc. Each of the three segments is a leg: the guide moves on to the next
    one near its end (:mod:`langenv.control.guide`). The tool turns with the arcs (``angle_deg``)
    and back along the line, as the study's handle did.

    Rotation sense: positive, right-handed about +z (counter-clockwise seen from above), so the
    hand moves towards +x. The SPEC fixes the pivot and the start but not the sense; we read "away
    from the body" as follows. The forearm points from the elbow (on the pivot axis) along -y, so
    the person faces -y and the torso lies beside the elbow along x. It cannot lie on the +x side:
    the robot's base (the origin) is there, 0.4 m from the elbow. So the torso is on the -x side
    and external rotation swings the hand to +x. The same sense keeps the hand well inside the
    UR5's reach (the opposite sense would take it to the edge of its 0.85 m reach).

    Args:
        angle_deg: Angle of the arcs (deg), in (0, 90].

    Returns:
        The trajectory (arc, line, arc).

    Raises:
        TrajectoryError: an angle outside (0, 90] deg.
    """
    angle = float(angle_deg)
    if not (math.isfinite(angle) and 0.0 < angle <= 90.0):
        raise TrajectoryError(f"default_exercise: angle_deg must lie in (0, 90], got {angle_deg!r}")
    start = np.array(EXERCISE_START)
    pivot = np.array(EXERCISE_PIVOT)
    up = np.array([0.0, 0.0, 1.0])
    rad = math.radians(angle)
    out = ArcSegment(center=pivot, axis=up, start=start, angle=rad, waypoint=True)
    back = LineSegment(start=out.end, end=start, waypoint=True, turn=rad)
    again = ArcSegment(center=pivot, axis=up, start=start, angle=rad, waypoint=True)
    return Trajectory([out, back, again])
