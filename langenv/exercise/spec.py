"""An exercise: named legs of lines, arcs and splines, the tool's turn, the speed, the script.

An exercise file (``langenv/assets/exercises/NAME.yaml``, read by :func:`~langenv.exercise.load.
load_exercise`) says in data what :func:`~langenv.control.trajectory.default_exercise` says in
code: where the hand starts, the legs it is guided along (each ends at a waypoint, where the guide
moves on), how the handle turns along them, the nominal hand speed and the phrase graph that
talks the person through. Units in the file: **m, deg, s**; they become SI (m, rad, s) once, at
load. Coordinates are the robot's base frame (z up, the table top at z = 0).

## The file

| key | type | unit | default | meaning |
|---|---|---|---|---|
| ``name`` | str | | required | identifier (``[a-z0-9_]``), the file's stem for a shipped one |
| ``title`` | str | | required | one line for ``list`` and figures |
| ``units`` | map | | ``{length: m, angle: deg, time: s}`` | must be exactly that when given |
| ``start`` | [x, y, z] | m | required | where the hand starts, at rest |
| ``speed`` | float | m/s | 0.125 | nominal hand speed: the guide's plateau ``F_prop / D0`` (0.02–0.25) |
| ``switch_tol`` | float | m, rad | 0.1 | the guide moves on to the next leg when the hand's pose is this close to the leg's end pose, in the lab's 6-D norm (SPEC §2); with a tool that does not turn that is this many metres before the end: 0.035 gives the study's 3.5 cm (0.01–0.1) |
| ``script.graph`` | str | | ``lc`` | phrase graph of the policies that choose phrases (graph role ``graph``: LC, its variants, learned aligners): a shipped graph name or a YAML path relative to the file |
| ``script.single`` | str | | ``lc-noap`` | the one-wording graph AC and LC-noAP say (graph role ``single``) |
| ``legs`` | list | | required | 1–40 legs, in order, each starting where the previous ends |

A leg is a map with ``name`` (unique) and exactly one of:

| key | fields | meaning |
|---|---|---|
| ``line`` | ``to: [x, y, z]`` or ``to: start`` (m) | straight to the point |
| ``arc`` | ``center: [x, y, z]`` (m), ``axis: [x, y, z]``, ``angle`` (deg, signed, 0 < abs <= 360) | rotation of the leg's start about the axis through ``center`` (right-handed); 360: a circle (kept as arcs of at most 180 deg) |
| ``spline`` | ``through: [[x, y, z], ...]`` (m, last = end), ``tolerance`` (m, default 0.001) | cubic spline through the points, fitted with lines and arcs within ``tolerance`` (:mod:`~langenv.exercise.curves`) |

optionally ``waypoint: [x, y, z]`` (m), where the leg is meant to end (``check`` refuses a leg
that ends more than 1 mm away: an arc's angle or a spline's last point written wrong), and
optionally ``tool: {turn: deg, axis: [x, y, z]}``: how far the handle turns over the leg
(signed, about ``axis``). An arc's tool turns with it by default (``turn = angle`` about its
axis); a line or spline keeps the tool still unless ``tool`` says otherwise. The simulated arm
holds the handle's home orientation (as in the study's simulation); the turn enters the lab's
6-D leg-switch test (SPEC §2) and the reach checks (IK with the orientation asked for).

A leg may end where it starts (a loop: a circle, a lobe of a figure eight): the guide moves on
only once the hand has gone round it (:mod:`langenv.control.guide`, "Loops"); a spline loop needs
at least two points on the way round, and a loop that the guide cannot tell from its start (one
never farther than 2 ``switch_tol`` from its end) is refused (problem kind ``loop``).

A comment block at the top of the file says what the patient does.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field, replace
from pathlib import Path
from types import MappingProxyType

import numpy as np

from langenv.control.admittance import AdmittanceParams
from langenv.control.trajectory import (
    MIN_LENGTH,
    ArcSegment,
    LineSegment,
    Segment,
    Trajectory,
    split_arc,
)
from langenv.errors import ConfigError, ExerciseError, TrajectoryError

__all__ = [
    "GRAPH_ROLES",
    "LEG_KINDS",
    "MAX_LEGS",
    "PROBLEM_KINDS",
    "SPEED_RANGE",
    "STUDY_EXERCISE",
    "SWITCH_TOL_RANGE",
    "Exercise",
    "Leg",
    "Problem",
    "rotation_about",
]

PROBLEM_KINDS = MappingProxyType(
    {
        "unreadable": "the file cannot be read, or is not YAML",
        "not_mapping": "the file, a leg or a section is not a mapping",
        "unknown_key": "a key the format does not know",
        "missing_key": "a required key is absent",
        "bad_value": "a value of the wrong type or outside its range",
        "bad_vector": "a point or axis that is not three finite numbers",
        "bad_units": "units other than m, deg, s",
        "leg_kind": "a leg that is not exactly one of line, arc, spline",
        "duplicate_leg": "two legs with one name",
        "degenerate": "a zero-length line, an arc whose start lies on its axis, a zero angle",
        "spline_fit": "a spline not fitted with lines and arcs within its tolerance",
        "bad_graph": "the script's phrase graph is missing or invalid",
        "unknown_leg": "the script's phrase graph marks a leg the exercise does not have, or "
        "marks legs out of the exercise's order",
        "gap": "a leg that does not end at its stated waypoint (where the next one starts)",
        "curvature": "a bend too tight to follow at the nominal speed",
        "path_error": "the guided hand would leave the path by more than the tolerance",
        "short_leg": "a leg shorter than the guide's switch distance",
        "loop": "a leg the guide would take as done before the hand has gone along it: a loop "
        "too small to go round, or one with no way round",
        "unreachable": "a point the UR5 cannot reach with the tool orientation asked for",
        "joint_margin": "a joint within the margin of the end of its range",
        "singular": "a pose near a singularity (manipulability below the bound)",
        "collision": "the arm touching the table or itself",
        "etc": "the motion ETC at cooperation 1 is not finite or disagrees with the reference",
        "duration": "the nominal motion time is outside what an episode allows",
    }
)
"""Every ``kind`` of :class:`Problem` (the stable names tests assert on) and what it means."""

GRAPH_ROLES = MappingProxyType(
    {
        "graph": "the exercise's phrase graph (script.graph): the policies that choose phrases "
        "(LC, its variants, learned aligners)",
        "single": "the exercise's one wording (script.single): AC and LC-noAP, the paper's "
        "baselines",
    }
)
"""What graph a policy speaks, by role (a policy declares its ``graph_role``; the exercise maps
the role to a graph: :meth:`Exercise.graph_for`). A policy brings a rule, not a script."""

STUDY_EXERCISE = "external_rotation"
"""The study's exercise (SPEC §2), whose words the shipped graphs say."""
LEG_KINDS = ("line", "arc", "spline")
"""The shapes a leg may take."""
MAX_LEGS = 40
"""Most legs in one exercise."""
SPEED_RANGE = (0.02, 0.25)
"""Nominal hand speeds accepted (m/s): the guided plateau ``F_prop / D0``; above 0.25 m/s a
therapy motion is no longer slow, and the safety limit (0.5 m/s) is near."""
SWITCH_TOL_RANGE = (0.01, 0.1)
"""Leg-switch tolerances accepted: from 1 cm to the lab's 0.1."""
TOLERANCE_RANGE = (1e-5, 0.01)
"""Spline fitting tolerances accepted (m)."""
_NAME = re.compile(r"[a-z0-9_]{1,64}")


@dataclass(frozen=True)
class Problem:
    """One thing wrong with an exercise.

    Attributes:
        kind: One of :data:`PROBLEM_KINDS`.
        leg: The leg's name, or None when the problem is not a leg's.
        point: Where in the leg: the sample along it (the arm's checks, one every 1 cm from
            its start), its segment (a bend too tight), or the spline's point (the format);
            None for the whole leg.
        detail: What is wrong and what is allowed, in words.
        at: Where along the leg it lies (m from the leg's start) for a check along the path,
            said instead of ``point`` (an internal sample or segment index); None otherwise.
    """

    kind: str
    leg: str | None
    point: int | None
    detail: str
    at: float | None = None

    def __post_init__(self) -> None:
        if self.kind not in PROBLEM_KINDS:
            raise ValueError(
                f"Problem.kind must be one of {sorted(PROBLEM_KINDS)}, got {self.kind!r}"
            )

    def __str__(self) -> str:
        where = f"leg {self.leg!r}: " if self.leg is not None else ""
        if self.at is not None:
            where += f"{self.at:.2f} m along it: "
        elif self.point is not None:
            where += f"point {self.point}: "
        return f"{where}{self.kind}: {self.detail}"


def rotation_about(axis: np.ndarray, angle: float) -> np.ndarray:
    """Rotation matrix (3, 3) of ``angle`` rad about the unit ``axis`` (right-handed)."""
    x, y, z = (float(v) for v in axis)
    c, s = math.cos(angle), math.sin(angle)
    k = np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])
    return np.eye(3) + s * k + (1.0 - c) * (k @ k)


def _vec(value: object, name: str) -> np.ndarray:
    arr = np.array(value, dtype=np.float64)
    if arr.shape != (3,) or not np.all(np.isfinite(arr)):
        raise ExerciseError([Problem("bad_vector", None, None, f"{name} must be 3 finite numbers")])
    arr.setflags(write=False)
    return arr


@dataclass(frozen=True, eq=False)
class Leg:
    """One leg of an exercise: a line, an arc or a spline from the previous leg's end.

    Args:
        name: Unique name in the exercise.
        kind: ``"line"``, ``"arc"`` or ``"spline"``.
        end: Line: end point, shape (3,), m.
        center: Arc: a point on its axis, shape (3,), m.
        axis: Arc: rotation axis, shape (3,) (normalised by the arc).
        angle: Arc: signed angle (rad).
        through: Spline: the points after the start, shape (k, 3), m (last = the leg's end).
        tolerance: Spline: fitting tolerance (m).
        tool_turn: Signed tool rotation over the leg (rad); None: an arc's ``angle``, else 0.
        tool_axis: Axis of the tool's turn, shape (3,); None: an arc's axis.
        waypoint: Where the author means the leg to end, shape (3,), m, or None: checked
            (``gap``), not used to build the path.

    Raises:
        ExerciseError: a field missing for its kind, or a value out of range.
    """

    name: str
    kind: str
    end: np.ndarray | None = None
    center: np.ndarray | None = None
    axis: np.ndarray | None = None
    angle: float = 0.0
    through: np.ndarray | None = None
    tolerance: float = 1e-3
    tool_turn: float | None = None
    tool_axis: np.ndarray | None = None
    waypoint: np.ndarray | None = None

    def __post_init__(self) -> None:
        bad = []
        if self.kind not in LEG_KINDS:
            bad.append(Problem("leg_kind", self.name, None, f"kind must be one of {LEG_KINDS}"))
        need = {"line": ("end",), "arc": ("center", "axis"), "spline": ("through",)}
        for key in need.get(self.kind, ()):
            if getattr(self, key) is None:
                bad.append(Problem("missing_key", self.name, None, f"{self.kind} needs {key!r}"))
        if bad:
            raise ExerciseError(bad)
        for key in ("end", "center", "axis", "tool_axis", "waypoint"):
            value = getattr(self, key)
            if value is not None:
                object.__setattr__(self, key, _vec(value, f"leg {self.name!r}: {key}"))
        if self.through is not None:
            pts = np.array(self.through, dtype=np.float64).reshape(-1, 3)
            pts.setflags(write=False)
            object.__setattr__(self, "through", pts)
        lo, hi = TOLERANCE_RANGE
        if not lo <= self.tolerance <= hi:
            raise ExerciseError(
                [Problem("bad_value", self.name, None, f"tolerance must lie in [{lo}, {hi}] m")]
            )
        if self.tool_turn is not None and self.tool_turn != 0.0:
            if self.tool_axis is None and self.kind != "arc":
                raise ExerciseError(
                    [Problem("missing_key", self.name, None, "tool.turn needs tool.axis here")]
                )

    @property
    def turn(self) -> float:
        """Signed tool turn over the leg (rad)."""
        if self.tool_turn is not None:
            return float(self.tool_turn)
        return float(self.angle) if self.kind == "arc" else 0.0

    @property
    def turn_axis(self) -> np.ndarray:
        """Unit axis of the tool's turn, shape (3,) (z when the tool does not turn)."""
        axis = self.tool_axis if self.tool_axis is not None else self.axis
        if axis is None:
            return np.array([0.0, 0.0, 1.0])
        return np.asarray(axis / np.linalg.norm(axis))

    def no_way_round(self, start: np.ndarray) -> Problem | None:
        """The problem of a leg from ``start`` that ends where it starts with no way round, or
        None: a line back to its own start (``degenerate``: zero length) or a spline back to its
        start through fewer than two points on the way (``loop``: it would go out and back
        along itself, or nowhere)."""
        if self.kind == "line" and self.end is not None:
            if float(np.linalg.norm(self.end - start)) < MIN_LENGTH:
                return Problem(
                    "degenerate",
                    self.name,
                    None,
                    "the line ends where it starts (zero length): there is nothing to guide "
                    "along. Drop the leg; for a loop, use an arc (angle: 360, tool: {turn: 0}) "
                    "or a spline through points around it",
                )
        if self.kind == "spline" and self.through is not None and len(self.through) < 3:
            if float(np.linalg.norm(self.through[-1] - start)) < MIN_LENGTH:
                k = len(self.through) - 1
                how = "goes out and back along itself" if k else "has no length"
                return Problem(
                    "loop",
                    self.name,
                    None,
                    f"the spline ends where it starts and passes through {k} point"
                    f"{'' if k == 1 else 's'} on the way: it {how}, with no way round. A loop "
                    "needs at least two points around it (three or four points of a circle "
                    "make a round one)",
                )
        return None

    def segments(self, start: np.ndarray) -> list[Segment]:
        """The leg's segments from ``start``, the last one ending the leg (a waypoint).

        Raises:
            TrajectoryError: a degenerate shape or a spline that cannot be fitted.
        """
        from langenv.exercise.curves import fit_spline

        turn = abs(self.turn)
        if self.kind == "line":
            assert self.end is not None
            return [LineSegment(start, self.end, True, turn)]
        if self.kind == "arc":
            assert self.center is not None and self.axis is not None
            own = None if self.tool_turn is None else turn  # None: the tool turns with the arc
            arc = ArcSegment(self.center, self.axis, start, self.angle, True, own)
            return list(split_arc(arc))  # more than half a turn: as the Trajectory keeps it
        assert self.through is not None
        segs = fit_spline(start, self.through, self.tolerance)
        total = sum(s.length for s in segs)
        last = len(segs) - 1
        return [
            replace(seg, waypoint=i == last, turn=turn * seg.length / total)
            for i, seg in enumerate(segs)
        ]


@dataclass(frozen=True, eq=False)
class Exercise:
    """A therapy exercise: its path in legs, the tool's turn, the nominal speed and its script.

    Args:
        name: Identifier (``[a-z0-9_]``, at most 64 characters).
        title: One line saying what it is.
        start: Where the hand starts, shape (3,), m (base frame).
        legs: The legs, in order (1 to :data:`MAX_LEGS`).
        speed: Nominal hand speed (m/s), in :data:`SPEED_RANGE`: the guide's plateau speed.
        switch_tol: The guide's leg-switch tolerance (6-D norm of m and rad), in
            :data:`SWITCH_TOL_RANGE` (the study's: 0.1).
        graph: Phrase graph of the aligners that choose phrases: a shipped graph's name or a
            YAML path.
        single: The one-wording graph that AC and LC-noAP say (a name or a path).
        description: What the patient does (the file's comment block), for ``list``.
        path: The file it was loaded from, or None.

    Attributes:
        trajectory: The path as the guide follows it (:class:`Trajectory`).
        leg_segments: Per leg, the ``(first, last)`` index of its segments in the trajectory.

    Raises:
        ExerciseError: every problem of the fields and the path's shape, at once.
    """

    name: str
    title: str
    start: np.ndarray
    legs: tuple[Leg, ...]
    speed: float = 0.125
    switch_tol: float = 0.1
    graph: str = "lc"
    single: str = "lc-noap"
    description: str = ""
    path: Path | None = None
    trajectory: Trajectory = field(init=False, repr=False)
    leg_segments: tuple[tuple[int, int], ...] = field(init=False, repr=False)

    def __post_init__(self) -> None:
        problems: list[Problem] = []
        if not isinstance(self.name, str) or not _NAME.fullmatch(self.name):
            problems.append(Problem("bad_value", None, None, "name must match [a-z0-9_]{1,64}"))
        lo, hi = SPEED_RANGE
        if not (isinstance(self.speed, int | float) and lo <= float(self.speed) <= hi):
            problems.append(Problem("bad_value", None, None, f"speed must lie in [{lo}, {hi}] m/s"))
        lo, hi = SWITCH_TOL_RANGE
        if not (isinstance(self.switch_tol, int | float) and lo <= float(self.switch_tol) <= hi):
            problems.append(
                Problem("bad_value", None, None, f"switch_tol must lie in [{lo}, {hi}]")
            )
        legs = tuple(self.legs)
        if not 1 <= len(legs) <= MAX_LEGS:
            problems.append(
                Problem("bad_value", None, None, f"1 to {MAX_LEGS} legs, got {len(legs)}")
            )
        names = [leg.name for leg in legs]
        for n in sorted({n for n in names if names.count(n) > 1}):
            problems.append(Problem("duplicate_leg", n, None, "two legs have this name"))
        if problems:
            raise ExerciseError(problems, self.path)
        start = _vec(self.start, "start")
        object.__setattr__(self, "start", start)
        object.__setattr__(self, "legs", legs)
        object.__setattr__(self, "speed", float(self.speed))
        object.__setattr__(self, "switch_tol", float(self.switch_tol))
        segments: list[Segment] = []
        spans: list[tuple[int, int]] = []
        cursor = start
        for leg in legs:
            closed = leg.no_way_round(cursor)
            if closed is not None:
                problems.append(closed)
                continue
            try:
                segs = leg.segments(cursor)
            except TrajectoryError as exc:
                kind = "spline_fit" if leg.kind == "spline" else "degenerate"
                problems.append(Problem(kind, leg.name, None, str(exc)))
                continue
            spans.append((len(segments), len(segments) + len(segs) - 1))
            segments.extend(segs)
            cursor = segs[-1].end
        if problems:
            raise ExerciseError(problems, self.path)
        try:
            traj = Trajectory(segments)
        except TrajectoryError as exc:  # a gap: cannot happen when each leg starts at the cursor
            raise ExerciseError([Problem("gap", None, None, str(exc))], self.path) from None
        object.__setattr__(self, "trajectory", traj)
        object.__setattr__(self, "leg_segments", tuple(spans))

    def admittance(self) -> AdmittanceParams:
        """The study's virtual dynamics (SPEC §2) with the propelling force that makes the
        exercise's nominal speed the guided plateau ``F_prop / D0`` (10 N at 0.125 m/s), and the
        exercise's leg-switch tolerance."""
        params = AdmittanceParams()
        force = self.speed * params.damping
        if force == params.propel_force and self.switch_tol == params.switch_tol:
            return params
        return replace(params, propel_force=force, switch_tol=self.switch_tol)

    def graph_for(self, role: str) -> str:
        """The phrase graph this exercise gives a policy of graph role ``role``
        (:data:`GRAPH_ROLES`): ``graph`` for ``"graph"``, ``single`` for ``"single"``.

        Raises:
            ConfigError: an unknown role (listing the known ones).
        """
        if role == "graph":
            return self.graph
        if role == "single":
            return self.single
        raise ConfigError(f"graph role must be one of {sorted(GRAPH_ROLES)}, got {role!r}")

    def script_warning(self, role: str) -> str | None:
        """A ``warning:`` line when the policies of graph role ``role`` would say the study's
        words (a shipped graph: ``script.<role>`` left out or naming one) on an exercise other
        than the study's; else None."""
        from langenv.speech.graph import SHIPPED_GRAPHS

        ref = self.graph_for(role)
        if self.name == STUDY_EXERCISE or ref.replace("_", "-") not in SHIPPED_GRAPHS:
            return None
        who = "AC and LC-noAP" if role == "single" else "LC and the policies that choose phrases"
        where = self.path.name if self.path is not None else self.name
        return (
            f"warning: {where}: script.{role} is the study's {ref!r} (the default where the file "
            f"leaves it out): {who} would say the words of its shoulder external rotation ('move "
            "your hand away from your body') on this exercise; write a script (docs/scripts.md) "
            f"and name it in script.{role}"
        )

    @property
    def leg_names(self) -> tuple[str, ...]:
        """The legs' names, in order."""
        return tuple(leg.name for leg in self.legs)

    def leg_span(self, k: int) -> tuple[float, float]:
        """Arc-length span ``(start, end)`` of leg ``k`` along the trajectory (m)."""
        first, last = self.leg_segments[k]
        t = self.trajectory
        return float(t.seg_start[first]), float(t.seg_end[last])

    def tool_rotation(self, s: float, home: np.ndarray) -> np.ndarray:
        """The handle's orientation asked for at arc length ``s`` (m), shape (3, 3).

        ``home`` (3, 3) is the orientation at the start; each leg turns it by its signed
        ``turn`` about its axis (base frame), linearly in arc length.
        """
        rot = np.asarray(home, dtype=np.float64)
        for k, leg in enumerate(self.legs):
            a, b = self.leg_span(k)
            frac = 1.0 if s >= b else max(0.0, (s - a) / (b - a))
            rot = rotation_about(leg.turn_axis, leg.turn * frac) @ rot
            if s < b:
                break
        return rot
