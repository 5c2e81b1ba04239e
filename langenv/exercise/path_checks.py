"""Checks of an exercise's path alone: waypoints, leg lengths, bends at its speed, the motion.

None of these needs the arm. Each returns :class:`~langenv.exercise.spec.Problem` records. The path
is continuous by construction (each leg starts where the previous one ends) and tangent-continuous
inside a leg (a spline's biarcs, :mod:`~langenv.exercise.curves`); between legs it may turn
sharply, even reverse: the guide switches legs there and the hand dips (as in the study).

* ``gap``: a leg's stated ``waypoint`` farther than :data:`WAYPOINT_TOL` from where the leg ends;
* ``short_leg``: a leg not longer than twice its switch distance (the guide would move on before
  the hand has set off);
* ``loop``: a leg (not a ``short_leg``) the guide would take as done before the hand is half-way
  along it, following the path (sampled every :data:`~langenv.control.guide.GATE_STEP`): a loop
  (a leg that ends where it starts) never farther than 2 ``switch_tol`` from its end, so the
  guide cannot tell its start from its end (:mod:`langenv.control.guide`, "Loops"), or a leg that
  passes that close to its end pose early. The message says how far from its end the leg goes
  and the ``switch_tol`` that would let it run. While a leg has this problem the guided motion is
  not judged (its run ends at once: ``duration`` and ``etc`` would only repeat it);
* ``curvature``: a bend of radius ``R`` whose centripetal acceleration at the nominal speed,
  ``v^2 / R``, exceeds :data:`~langenv.control.guide.GOVERNOR_SHARE` of the velocity command's
  acceleration limit: the command can change at most at ``max_acceleration`` (a UR's ``speedL``),
  and, as the guide's speed governor does, half of it stays for the guide's corrections. One
  problem per leg, at its tightest bend, with the speed that bend allows (``sqrt(a R)``);
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
from langenv.control.guide import GATE_REACH, GATE_STEP, GOVERNOR_SHARE, Guide, GuideState
from langenv.control.trajectory import ArcSegment
from langenv.exercise.spec import SPEED_RANGE, SWITCH_TOL_RANGE, Exercise, Problem

__all__ = [
    "DURATION_RANGE",
    "ETC_AGREEMENT",
    "PATH_TOL",
    "WAYPOINT_TOL",
    "GuidedRun",
    "guided_run",
    "leg_times",
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
        leg_times: Time the hand spends in each leg (s, from the guide's switch into it to the
            switch out of it, the last leg to the motion's end); empty if it did not finish.
    """

    time: float | None
    etc: float
    max_path_error: float
    max_speed: float
    leg_times: tuple[float, ...] = ()


def guided_run(exercise: Exercise, params: AdmittanceParams | None = None) -> GuidedRun:
    """Simulate the guided motion (no force from the person, pace 1) and the fast ETC at rest."""
    from langenv.control.motion_etc import FastETC
    from langenv.control.virtual_loop import simulate_virtual

    params = params if params is not None else exercise.admittance()
    run = simulate_virtual(exercise.trajectory, params, t_max=DURATION_RANGE[1] * 1.5)
    etc = FastETC(Guide(exercise.trajectory, params), VariableAdmittance(params)).nominal()
    legs = (
        ()
        if run.done_time is None
        else leg_times(run.t, run.leg, len(exercise.legs), run.done_time)
    )
    return GuidedRun(run.done_time, float(etc), run.max_path_error, run.max_speed, legs)


def leg_times(t: np.ndarray, leg: np.ndarray, n_legs: int, end: float) -> tuple[float, ...]:
    """Time spent in each of ``n_legs`` legs (s) by a motion whose leg index at the times ``t``
    is ``leg`` and which ended at ``end``: from the first sample in a leg to the first in the
    next (the last: to ``end``); 0 for a leg it never reached."""
    starts = [float(t[np.argmax(leg >= k)]) if (leg >= k).any() else end for k in range(n_legs)]
    return tuple(max(0.0, b - a) for a, b in zip(starts, [*starts[1:], end], strict=True))


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
    if any(p.kind == "loop" for p in out):
        return out, run  # the guide would move on at once: the run says nothing more
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
        short = span[1] - span[0] <= 2.0 * q_sw
        if short:
            out.append(
                Problem(
                    "short_leg",
                    leg.name,
                    None,
                    f"{span[1] - span[0]:.3f} m long, the guide moves on {q_sw:.3f} m before "
                    "its end (a leg must be longer than twice that)",
                )
            )
        loop = None if short else _early_switch(exercise, guide, k, params.switch_tol)
        if loop is not None:
            out.append(loop)
        bends = [(seg.radius, j) for j, seg in enumerate(segs) if isinstance(seg, ArcSegment)]
        radius, j = min(bends, default=(math.inf, -1))
        if v * v / radius > a_lat:
            fits = math.sqrt(a_lat * radius)
            speed = (
                f"a speed of at most {math.floor(fits * 1000) / 1000:.3f} m/s"
                if fits >= SPEED_RANGE[0]
                else f"no speed allowed (>= {SPEED_RANGE[0]} m/s) is that slow"
            )
            out.append(
                Problem(
                    "curvature",
                    leg.name,
                    j,
                    f"a bend of radius {radius:.3f} m (its tightest) needs "
                    f"{v * v / radius:.3f} m/s^2 at {v} m/s (at most {a_lat:.3f}): {speed}, or "
                    f"bends of radius >= {v * v / a_lat:.3f} m",
                )
            )
    return out


def _early_switch(exercise: Exercise, guide: Guide, k: int, tol: float) -> Problem | None:
    """The ``loop`` problem of leg ``k``, or None: where a hand following the path would make
    the guide move on (pose within ``tol`` of the end pose, closest point past the gate)."""
    traj = exercise.trajectory
    a, b = exercise.leg_span(k)
    n = max(2, math.ceil((b - a) / GATE_STEP) + 1)
    gate = guide.gate(k)
    end = traj.position(b)
    half = a + 0.5 * (b - a)
    for i in range(n):
        s = a + (b - a) * i / (n - 1)
        if s >= half:
            return None
        if s >= gate and guide.pose_distance(GuideState(s, k, False), traj.position(s)) < tol:
            break
    gap = float(np.linalg.norm(traj.position(a) - end))
    far = max(  # how far from its end the leg goes after that pass
        float(np.linalg.norm(traj.position(a + (b - a) * j / (n - 1)) - end)) for j in range(i, n)
    )
    reach = GATE_REACH * tol
    lo = SWITCH_TOL_RANGE[0]
    most = math.floor(far / GATE_REACH * 1000.0 - 1e-9) / 1000.0
    fix = f"or set switch_tol to at most {most:.3f}" if most >= lo else f"(switch_tol >= {lo})"
    where = "at its start" if s == a else f"{s - a:.3f} m into it"
    if gap < tol:
        why = (
            f"it ends {gap:.3f} m from where it starts (a loop) and never goes farther than "
            f"{far:.3f} m from its end, so the guide cannot tell going round it from not having "
            f"started (a loop must reach more than {GATE_REACH:g} switch_tol = {reach:.3f} m from "
            f"its end): make it wider, {fix}"
        )
    else:
        why = (
            f"the hand passes within switch_tol ({tol}) of its end pose there and the leg goes "
            f"no farther than {far:.3f} m from its end after that, so the guide cannot tell that "
            f"pass from the end (it can when the leg goes more than {GATE_REACH:g} switch_tol = "
            f"{reach:.3f} m away in between): keep the path farther from its end, {fix}"
        )
    return Problem(
        "loop",
        exercise.legs[k].name,
        None,
        f"the guide would take this {b - a:.3f} m leg as done {where}: {why}",
    )
