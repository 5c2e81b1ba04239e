"""The guide: progress along the trajectory, leg switching, and the virtual force (SPEC §1, §2).

``F_virtual = K (x_d - x) + F_prop b (+ centripetal feed-forward on arcs)``, where ``x_d = T(s)``
is the closest point, found locally around the previous one and only inside the current leg
``[previous waypoint, next waypoint]``, and ``b`` the unit tangent there.

Legs, as in the study's lab code (SPEC §2, "segment ends"). The full propelling force acts along
the path until the leg's end is passed; past it the closest point is clamped to the end, so only
the guide term ``K (T(end) - x)`` acts, pulling the hand back. The guide moves on to the next leg
as soon as the hand's pose is within ``switch_tol`` of the leg's end pose, in the lab's 6-D norm
``sqrt(|x - T(end)|^2 + dphi^2)`` with ``dphi`` the tool rotation still to go (the tool turns with
the path, :meth:`~langenv.control.trajectory.Trajectory.tool_angle`), without waiting for the hand
to slow down: about 3.5 cm before the end point on the default exercise. The hand then turns
towards the next leg in a short V-shaped dip of its speed. Motion is over when the last leg's end
pose is reached the same way; the robot then holds still.

Loops (an addition to the study: its legs never come back near their own ends). A leg may pass
near its end before it gets there: a loop that ends where it starts (a circle, a lobe of a
figure eight), or a leg that crosses its own end point on the way. The pose test alone would take
such a leg as done before the hand has gone round it. So each leg also has a *gate*
(:meth:`Guide.gate`), an arc length the closest point must have reached for the guide to move on:

* the leg's *final approach* is the stretch that ends at its end point and, walking back from
  there, stays within ``GATE_REACH * switch_tol`` (2 switch_tol) of that point (the path sampled
  every :data:`GATE_STEP`);
* a leg that comes within that distance of its end point before its final approach *returns*:
  its gate is where its final approach begins (the sample before it, where the path is still
  that far from the end). The guide moves on when the pose is within ``switch_tol`` of the end
  pose *and* the closest point is at or past the gate, so the hand must go round first;
* any other leg's gate is its start. The closest point never lies before its leg's start (its
  window), so the gate adds nothing there and the switch is the lab's, to the bit. No leg of a
  shipped exercise returns (``tests/test_loops.py`` checks it).

Why 2 switch_tol: when the pose test passes, the hand is within ``switch_tol`` of the end point and
its closest point is no farther from it than the end point is, so the closest point lies within
2 switch_tol of the end point: on the final approach, past the gate, for a hand that has come
round. A leg that never goes that far from its end (a loop less than 2 switch_tol across) and
starts within ``switch_tol`` of its end pose cannot be gone round: the checks refuse it (problem
kind ``loop``, :mod:`langenv.exercise.path_checks`). The closest point's search stays local
inside the leg: at a loop's start it starts from the leg's start (the window's low end, so it
cannot wrap back to the loop's end), and near the loop's end the window's high end stops it; arcs
of more than half a turn are split (:func:`~langenv.control.trajectory.split_arc`) so that no
segment's own projection wraps round either.

Speed governor (an addition to the study, :meth:`Guide.speed_limit`). The hand follows ``v_ref``
changing its velocity at most at ``max_acceleration``, so a hand that a person pushes along
faster than the guided plateau speed ``F_prop / D0`` would overshoot the corners (by 20 cm at
0.25 m/s) and leave the arcs. While a person pushes the hand along, the command is therefore
capped at the speed from which the hand can still brake to the plateau speed by the switch
point, at the plateau speed while it turns into a new leg, and on arcs at the speed whose
centripetal acceleration is half the limit (0.16 m/s on the default arcs), planning with half the
limit so that the other half stays for the guide's corrections. Without a helping push (the
study's sessions, and the motion ETC's assumption) the governor does nothing.

Curvature feed-forward (an addition to the paper, switch ``curvature_feedforward``). On an arc of
radius R the hand needs a centripetal force ``M0 v^2 / R``; without it the guide spring supplies it
from a lateral offset ``M0 v^2 / (R K)``, about 1.2 cm at the default parameters on the 0.368 m
arc. We add ``M0 kappa (v_par / p)^2`` (``kappa`` the curvature vector, ``v_par = v . b``); the
admittance multiplies forces by ``p^2``, so it yields exactly ``kappa v_par^2`` of acceleration at
any pace, and, scaling with ``(v / p)^2``, it keeps the time-warp property. It is not applied
while the closest point sits clamped at the leg's end.

``update`` and ``virtual_force`` run at 500 Hz; they work on plain floats (about 2-3 us each).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from langenv.control.admittance import AdmittanceParams
from langenv.control.trajectory import Trajectory
from langenv.errors import ConfigError
from langenv.layout import Layout, field_table

__all__ = [
    "GATE_REACH",
    "GATE_STEP",
    "GOVERNOR_SHARE",
    "GUIDE_SETTINGS",
    "GUIDE_STATE",
    "LEG",
    "TURNED_COS2",
    "Guide",
    "GuideState",
    "switch_gate",
]

GOVERNOR_SHARE = 0.5
"""Share of ``max_acceleration`` the speed governor plans its braking and turning with (the rest
is left for the guide's corrections)."""
TURNED_COS2 = math.cos(math.radians(25.0)) ** 2
"""The governor's hand is still turning into a leg while its command is more than 25 deg off
the leg's direction (cos^2 of that angle)."""
GATE_REACH = 2.0
"""A leg's final approach stays within this many ``switch_tol`` of its end point (module
docstring, "Loops")."""
GATE_STEP = 0.001
"""Spacing (m) of the samples of a leg that :func:`switch_gate` measures."""


def switch_gate(trajectory: Trajectory, start: float, end: float, reach: float) -> float:
    """The gate of the leg ``[start, end]``: where its closest point must be for a switch (m).

    ``start`` if the path stays farther than ``reach`` from the leg's end point everywhere before
    its final approach (the stretch that ends there and stays within ``reach`` of it), else the
    arc length just before the final approach (module docstring, "Loops"). The leg is sampled
    every :data:`GATE_STEP` (at least at its two ends).

    Args:
        trajectory: The path.
        start: Arc length of the leg's start (m).
        end: Arc length of the leg's end (m), ``> start``.
        reach: Radius of the final approach (m), ``> 0``.

    Returns:
        The gate's arc length, in ``[start, end]`` (m).
    """
    n = max(2, math.ceil((end - start) / GATE_STEP) + 1)
    seg, t = trajectory.locate(end, True)
    e0, e1, e2 = seg.point(t)
    far = reach * reach
    ss = [start + (end - start) * i / (n - 1) for i in range(n)]
    d2 = []
    for s in ss:
        seg, t = trajectory.locate(s)
        p = seg.point(t)
        d2.append((p[0] - e0) ** 2 + (p[1] - e1) ** 2 + (p[2] - e2) ** 2)
    approach = n - 1
    while approach > 0 and d2[approach - 1] < far:
        approach -= 1
    if approach == 0:  # the whole leg lies within reach of its end: nothing to tell apart
        return start
    gate = approach - 1  # the last sample at least ``reach`` from the end
    returns = any(d < far for d in d2[:gate])
    return ss[gate] if returns else start


GUIDE_STATE = field_table(
    """
    s          arc length of the closest point (m)
    leg:int    the leg being guided (the number of legs once done)
    done:bool  the last leg's end has been reached
    """
)
"""The guide's state (:class:`GuideState`), declared for the compiled tick."""
GUIDE_SETTINGS = field_table(
    """
    k               guide stiffness K (N/m)
    f_prop          propelling force (N)
    tol2            the switch tolerance's square (m^2, rad^2)
    ff_mass         mass of the curvature feed-forward (kg; 0: off)
    acc             the command's acceleration limit (m/s^2; inf: no governor)
    v_turn2         the guided plateau speed's square (m^2/s^2)
    end_tangent[3]  the direction of progress once done
    n_legs:int      number of legs
    """
)
"""The guide's settings (:meth:`Guide.settings`)."""
LEG = Layout(
    "leg",
    field_table(
        """
        start         the leg's start (arc length, m)
        end           its end (arc length, m)
        end_point[3]  its end point (m)
        end_angle     the tool's running turn at its end (rad)
        switch        its switch distance before the end (m)
        gate          its gate (arc length, m; :meth:`Guide.gate`)
        """
    ),
)
"""One leg's row (:meth:`Guide.leg_rows`)."""


@dataclass
class GuideState:
    """Progress of the guide (mutable; :meth:`copy` is cheap).

    Attributes:
        s: Arc length of the closest point (m).
        leg: Index of the leg being guided, into ``trajectory.waypoint_s`` (its end); equal to
            the number of legs once ``done``.
        done: Whether the last leg's end has been reached (motion over).
    """

    s: float
    leg: int
    done: bool

    def copy(self) -> GuideState:
        """An independent copy."""
        return GuideState(self.s, self.leg, self.done)


class Guide:
    """Progress tracking, leg switching and the virtual force along a trajectory.

    Args:
        trajectory: The exercise path.
        params: Stiffness, propelling force, switching tolerance, mass (feed-forward).

    Raises:
        ConfigError: an argument of the wrong type.
    """

    def __init__(self, trajectory: Trajectory, params: AdmittanceParams) -> None:
        if not isinstance(trajectory, Trajectory):
            raise ConfigError(
                f"Guide: trajectory must be a Trajectory, got {type(trajectory).__name__}"
            )
        if not isinstance(params, AdmittanceParams):
            raise ConfigError(
                f"Guide: params must be AdmittanceParams, got {type(params).__name__}"
            )
        self.trajectory = trajectory
        self.params = params
        ends = [float(s) for s in trajectory.waypoint_s]
        self._ends = ends
        self._starts = [0.0, *ends[:-1]]
        self._end_pts = [tuple(trajectory.position(s).tolist()) for s in ends]
        self._end_angle = [trajectory.tool_angle(s) for s in ends]
        self._n_legs = len(ends)
        self._k = params.stiffness
        self._f_prop = params.propel_force
        self._tol2 = params.switch_tol**2
        self._ff_mass = params.mass if params.curvature_feedforward else 0.0
        self._acc = params.max_acceleration
        self._v_turn2 = params.plateau_speed**2
        self._q_sw = [self.switch_distance(k) for k in range(self._n_legs)]
        reach = GATE_REACH * params.switch_tol
        self._gate = [
            switch_gate(trajectory, a, b, reach) for a, b in zip(self._starts, ends, strict=True)
        ]

    def settings(self) -> dict[str, float | tuple[float, ...]]:
        """The guide's settings by the names of :data:`GUIDE_SETTINGS`."""
        return {
            "k": self._k, "f_prop": self._f_prop, "tol2": self._tol2, "ff_mass": self._ff_mass,
            "acc": self._acc, "v_turn2": self._v_turn2, "n_legs": self._n_legs,
            "end_tangent": tuple(self.tangent(GuideState(self._ends[-1], self._n_legs, True))),
        }  # fmt: skip

    def leg_rows(self) -> np.ndarray:
        """The legs as rows of :data:`LEG`, shape ``(n_legs, LEG.size)``."""
        rows = np.zeros((self._n_legs, LEG.size))
        for j in range(self._n_legs):
            LEG.pack(
                rows[j],
                {
                    "start": self._starts[j], "end": self._ends[j], "end_point": self._end_pts[j],
                    "end_angle": self._end_angle[j], "switch": self._q_sw[j],
                    "gate": self._gate[j],
                },
            )  # fmt: skip
        return rows

    @property
    def n_legs(self) -> int:
        """Number of legs (the last one ends at the end of the trajectory)."""
        return self._n_legs

    def initial_state(self) -> GuideState:
        """State at the start of the trajectory, on its first leg."""
        return GuideState(s=0.0, leg=0, done=False)

    def window(self, state: GuideState) -> tuple[float, float]:
        """Arc-length span ``(start, end)`` of the current leg (m): the closest point's window."""
        k = min(state.leg, self._n_legs - 1)
        return self._starts[k], self._ends[k]

    def gate(self, leg: int) -> float:
        """Arc length (m) the closest point must have reached on ``leg`` before the guide moves
        on: the leg's start, or where a leg that returns near its end begins its final approach
        (:func:`switch_gate`, module docstring "Loops")."""
        return self._gate[leg]

    def returns(self, leg: int) -> bool:
        """Whether ``leg`` comes back near its end before its final approach (a loop): its gate
        is not its start."""
        return self._gate[leg] > self._starts[leg]

    def switch_distance(self, leg: int) -> float:
        """How far before the end of ``leg`` (m, along the path) the guide moves on.

        On the path the 6-D distance to the end pose at ``q`` metres before it is
        ``q sqrt(1 + w^2)``, ``w`` the tool's turn per metre there, so the switch happens at
        ``q = switch_tol / sqrt(1 + w^2)`` (3.45 cm on the default exercise's arcs).
        """
        w = self.trajectory.turn_rate(self._ends[leg], arriving=True)
        return self.params.switch_tol / math.sqrt(1.0 + w * w)

    def speed_limit(self, state: GuideState, v_cmd: np.ndarray) -> float:
        """Top speed of the velocity command at the closest point (m/s): the speed governor.

        ``sqrt(v_turn^2 + 2 a' (q - q_sw))`` with ``q`` the distance left to the leg's end,
        ``q_sw`` its switch distance, ``v_turn = F_prop / D0`` (the guided plateau speed) and
        ``a' = GOVERNOR_SHARE * max_acceleration``, and on an arc at most ``sqrt(a' R)``; while
        the hand is still turning into the leg (its command less than 25 deg off the leg's
        direction) ``v_turn``; ``inf`` without an acceleration limit.

        Args:
            state: Guide state.
            v_cmd: The velocity command now, shape (3,), m/s.
        """
        acc = self._acc
        if acc == math.inf or state.done:
            return math.inf
        k = state.leg
        seg, t = self.trajectory.locate(state.s, state.s >= self._ends[k])
        b = seg.unit_tangent(t)
        c0, c1, c2 = v_cmd.tolist()
        along = c0 * b[0] + c1 * b[1] + c2 * b[2]
        if along * along < TURNED_COS2 * (c0 * c0 + c1 * c1 + c2 * c2) or along < 0.0:
            return math.sqrt(self._v_turn2)
        room = self._ends[k] - state.s - self._q_sw[k]
        acc *= GOVERNOR_SHARE
        cap = math.sqrt(self._v_turn2 + 2.0 * acc * (room if room > 0.0 else 0.0))
        radius = getattr(seg, "radius", None)
        if radius is not None:
            bend = math.sqrt(acc * radius)
            cap = bend if bend < cap else cap
        return cap

    def tangent(self, state: GuideState, x: np.ndarray | None = None) -> np.ndarray:
        """Direction of progress at the closest point, shape (3,): where the hand is guided.

        On the leg it is the unit tangent ``b`` there; unlike :meth:`Trajectory.tangent` (the
        right derivative), at the current leg's end it is the tangent of the segment *arriving*
        there. A hand that has gone past the leg's end without coming close enough to switch is
        guided back to the end point: given ``x``, the direction is then towards it. Users push
        along it to help and against it to resist. Once motion is over it is the tangent at the
        end of the trajectory.

        Args:
            state: Guide state.
            x: Hand position, shape (3,), m; ``None``: the path's direction only.

        Returns:
            Unit vector, shape (3,).
        """
        if state.done:
            seg, t = self.trajectory.locate(self._ends[-1], True)
            return np.array(seg.unit_tangent(t))
        end = self._ends[state.leg]
        seg, t = self.trajectory.locate(state.s, state.s >= end)
        b = seg.unit_tangent(t)
        if x is not None and state.s >= end:
            p = self._end_pts[state.leg]
            x0, x1, x2 = x.tolist()
            d0, d1, d2 = p[0] - x0, p[1] - x1, p[2] - x2
            past = -(d0 * b[0] + d1 * b[1] + d2 * b[2])
            if past > 1e-6:  # beyond the end point: guided back to it
                n = math.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
                return np.array((d0 / n, d1 / n, d2 / n))
        return np.array(b)

    def pose_distance(self, state: GuideState, x: np.ndarray) -> float:
        """The lab's 6-D distance (m, rad) from the hand's pose to the current leg's end pose."""
        k = min(state.leg, self._n_legs - 1)
        p = self._end_pts[k]
        x0, x1, x2 = x.tolist()
        d0, d1, d2 = x0 - p[0], x1 - p[1], x2 - p[2]
        dphi = self._end_angle[k] - self.trajectory.tool_angle(state.s)
        return math.sqrt(d0 * d0 + d1 * d1 + d2 * d2 + dphi * dphi)

    def update(self, state: GuideState, x: np.ndarray) -> None:
        """Move the closest point to the hand and move on to the next leg when its end is near.

        Mutates ``state``: ``s`` (local closest point inside the current leg); when the pose is
        within ``switch_tol`` of the leg's end pose and ``s`` has reached the leg's
        :meth:`gate`, ``leg`` advances (``s`` stays, and the next tick's search starts from the
        next leg's start; ``done`` at the last leg, with ``s`` at the end).

        Args:
            state: Guide state, updated in place.
            x: Hand position, shape (3,), m.
        """
        if state.done:
            return
        k = state.leg
        x0, x1, x2 = x.tolist()
        s_end = self._ends[k]
        s = self.trajectory.closest_xyz(x0, x1, x2, state.s, self._starts[k], s_end)
        state.s = s
        p = self._end_pts[k]
        d0, d1, d2 = x0 - p[0], x1 - p[1], x2 - p[2]
        dphi = self._end_angle[k] - self.trajectory.tool_angle(s)
        if d0 * d0 + d1 * d1 + d2 * d2 + dphi * dphi < self._tol2 and s >= self._gate[k]:
            state.leg = k + 1
            if k + 1 >= self._n_legs:
                state.done = True
                state.s = s_end

    def virtual_force(
        self, state: GuideState, x: np.ndarray, v: np.ndarray, p: float
    ) -> np.ndarray:
        """``F_virtual`` at the current state.

        Args:
            state: Guide state (after :meth:`update` for this tick).
            x: Hand position, shape (3,), m.
            v: Hand (reference) velocity, shape (3,), m/s.
            p: Physical pace (divides the along-path speed in the feed-forward), > 0.

        Returns:
            Force, shape (3,), N (a new array).
        """
        x0, x1, x2 = x.tolist()
        k_s = self._k
        if state.done:
            e = self._end_pts[-1]
            return np.array((k_s * (e[0] - x0), k_s * (e[1] - x1), k_s * (e[2] - x2)))
        s = state.s
        clamped = s >= self._ends[state.leg]
        seg, t = self.trajectory.locate(s, clamped)
        xd, b, kv = seg.frame(t)
        f0, f1, f2 = k_s * (xd[0] - x0), k_s * (xd[1] - x1), k_s * (xd[2] - x2)
        if clamped:
            return np.array((f0, f1, f2))
        fp = self._f_prop
        f0 += fp * b[0]
        f1 += fp * b[1]
        f2 += fp * b[2]
        if kv is not None and self._ff_mass:
            v0, v1, v2 = v.tolist()
            vp = (v0 * b[0] + v1 * b[1] + v2 * b[2]) / p
            c = self._ff_mass * vp * vp
            f0 += c * kv[0]
            f1 += c * kv[1]
            f2 += c * kv[2]
        return np.array((f0, f1, f2))
