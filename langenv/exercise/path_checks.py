"""Checks of an exercise's path alone: waypoints, leg lengths, bends at its speed, the motion.

None of these needs the arm. Each returns :class:`~langenv.exercise.spec.Problem` records. The path
is continuous by construction (each leg starts where the previous one ends) and tangent-continuous
inside a leg (a spline's biarcs, :mod:`~langenv.exercise.curves`); between legs it may turn
sharply, even reverse: the guide switches legs there and the hand dips (as in the study).

* ``gap``: a leg's stated ``waypoint`` farther than :data:`WAYPOINT_TOL` from where the leg ends;
* ``short_leg``: a leg not longer than twice its switch distance (the guide would move on before
  the hand has set off);
* ``curvature``: a bend of radius ``R`` whose centripetal acceleration at the nominal speed,
  ``v^2 / R``, exceeds :data:`~langenv.control.guide.GOVERNOR_SHARE` of the velocity command's
  acceleration limit: the command can change at most at ``max_acceleration`` (a UR's ``speedL``),
  and, as the guide's speed governor does, half of it stays for the guide's corrections;
* ``path_error``, ``etc``, ``duration``: the guided motion at cooperation 1 and pace 1, simulated
  (:func:`~langenv.control.virtual_loop.simulate_virtual`, the reference of the motion ETC): it
  must finish, stay within :data:`PATH_TOL` of the path, last between the bounds of
  :data:`DURATION_RANGE`, and the fast motion ETC (:class:`~langenv.control.motion_etc.FastETC`)
  must agree with it within :data:`ETC_AGREEMENT`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from langenv.control.admittance import AdmittanceParams, VariableAdmittance
from langenv.control.guide import GOVERNOR_SHARE, Guide
from langenv.control.trajectory import ArcSegment
from langenv.exercise.spec import Exercise, Problem

__all__ = [
    "DURATION_RANGE",
    "ETC_AGREEMENT",
    "PATH_TOL",
    "WAYPOINT_TOL",
    "GuidedRun",
    "guided_run",
    "path_problems",
]

WAYPOINT_TOL = 1e-3
"""Largest distance (m) between a leg's stated ``waypoint`` and where its path ends."""
PATH_TOL = 0.05
"""Largest distance (m) of the guided hand from the path at cooperation 1: half the protective
stop's ``max_deviation`` (0.10 m), so a person's push keeps room before a stop. The study's
exercise reaches 0.034 m where the guide cuts the corners between legs."""
DURATION_RANGE = (4.0, 40.0)
"""Nominal motion times accepted (s): at least a few phrases long, at most the observation's
time scale (``T_SCALE``, 40 s), well inside an episode's 60 s."""
ETC_AGREEMENT = (0.3, 0.03)
"""The fast motion ETC must agree with the simulated run within ``max(0.3 s, 3 %)``."""


@dataclass(frozen=True)
class GuidedRun:
    """The guided motion of an exercise at cooperation 1 and pace 1.

    Attributes:
        time: Simulated motion time (s), None if it did not finish within the horizon.
        etc: The fast motion ETC from rest at the start (s).
        max_path_error: Largest distance of the hand from the path (m).
        max_speed: Largest hand speed (m/s).
    """

    time: float | None
    etc: float
    max_path_error: float
    max_speed: float


def guided_run(exercise: Exercise, params: AdmittanceParams | None = None) -> GuidedRun:
    """Simulate the guided motion (no force from the person, pace 1) and the fast ETC at rest."""
    from langenv.control.motion_etc import FastETC
    from langenv.control.virtual_loop import simulate_virtual

    params = params if params is not None else exercise.admittance()
    run = simulate_virtual(exercise.trajectory, params, t_max=DURATION_RANGE[1] * 1.5)
    etc = FastETC(Guide(exercise.trajectory, params), VariableAdmittance(params)).nominal()
    return GuidedRun(run.done_time, float(etc), run.max_path_error, run.max_speed)


def path_problems(
    exercise: Exercise, params: AdmittanceParams | None = None
) -> tuple[list[Problem], GuidedRun]:
    """The path's problems (module docstring) and its guided run.

    Args:
        exercise: The exercise.
        params: Virtual dynamics; None: :meth:`Exercise.admittance`.

    Returns:
        ``(problems, run)``.
    """
    params = params if params is not None else exercise.admittance()
    out = _shape_problems(exercise, params)
    run = guided_run(exercise, params)
    if run.time is None:
        out.append(Problem("etc", None, None, "the guided hand does not finish the exercise"))
        return out, run
    lo, hi = DURATION_RANGE
    if not lo <= run.time <= hi:
        out.append(
            Problem(
                "duration", None, None, f"nominal motion time {run.time:.1f} s, allowed {lo}-{hi} s"
            )
        )
    if run.max_path_error > PATH_TOL:
        out.append(
            Problem(
                "path_error",
                None,
                None,
                f"the guided hand strays {run.max_path_error:.3f} m from the path (at most "
                f"{PATH_TOL} m)",
            )
        )
    slack = max(ETC_AGREEMENT[0], ETC_AGREEMENT[1] * run.time)
    if not (math.isfinite(run.etc) and abs(run.etc - run.time) <= slack):
        out.append(
            Problem(
                "etc",
                None,
                None,
                f"motion ETC at cooperation 1 is {run.etc:.2f} s, the simulated motion "
                f"{run.time:.2f} s (allowed difference {slack:.2f} s)",
            )
        )
    return out, run


def _shape_problems(exercise: Exercise, params: AdmittanceParams) -> list[Problem]:
    out: list[Problem] = []
    traj = exercise.trajectory
    guide = Guide(traj, params)
    a_lat = GOVERNOR_SHARE * params.max_acceleration
    v = exercise.speed
    for k, leg in enumerate(exercise.legs):
        first, last = exercise.leg_segments[k]
        segs = traj.segments[first : last + 1]
        end = segs[-1].end
        if leg.waypoint is not None:
            miss = float(np.linalg.norm(end - leg.waypoint))
            if miss > WAYPOINT_TOL:
                out.append(
                    Problem(
                        "gap",
                        leg.name,
                        None,
                        f"the leg ends at {np.round(end, 4).tolist()}, {miss:.4f} m from its "
                        f"waypoint {leg.waypoint.tolist()} (at most {WAYPOINT_TOL} m)",
                    )
                )
        span = exercise.leg_span(k)
        q_sw = guide.switch_distance(k)
        if span[1] - span[0] <= 2.0 * q_sw:
            out.append(
                Problem(
                    "short_leg",
                    leg.name,
                    None,
                    f"{span[1] - span[0]:.3f} m long, the guide moves on {q_sw:.3f} m before "
                    "its end (a leg must be longer than twice that)",
                )
            )
        for j, seg in enumerate(segs):
            if isinstance(seg, ArcSegment) and v * v / seg.radius > a_lat:
                out.append(
                    Problem(
                        "curvature",
                        leg.name,
                        j,
                        f"a bend of radius {seg.radius:.3f} m needs {v * v / seg.radius:.3f} m/s^2 "
                        f"at {v} m/s (at most {a_lat:.3f}: radius >= {v * v / a_lat:.3f} m, or a "
                        "lower speed)",
                    )
                )
    return out
