"""The safety layer compiled (:mod:`langenv.robot.safety`): the command limits
(:func:`~langenv.robot.safety.limit_velocity`) and the monitor's checks
(:meth:`SafetyMonitor.check <langenv.robot.safety.SafetyMonitor.check>`), the same operations in the
same order (``tests/test_compiled_tick.py``)."""

from __future__ import annotations

import math

import numpy as np

from langenv.kernels import inline, kernel
from langenv.robot.safety import HOLD_TIME, JOINT_CHECK_MAX

__all__ = [
    "STOP_DEVIATION",
    "STOP_FORCE",
    "STOP_JOINT",
    "STOP_NONE",
    "STOP_SPEED",
    "check",
    "check_joints",
    "limit_velocity",
]

STOP_NONE, STOP_FORCE, STOP_DEVIATION, STOP_SPEED, STOP_JOINT = 0, 1, 2, 3, 4
"""The monitor's answers: no breach, or the limit breached."""


@kernel
def limit_velocity(
    v0: float,
    v1: float,
    v2: float,
    o0: float,
    o1: float,
    o2: float,
    hold: float,
    vmax: float,
) -> tuple[float, float, float]:
    """:func:`~langenv.robot.safety.limit_velocity` of ``v`` at the offset ``o`` from the path
    (``changed`` or not, the values are the same)."""
    d2 = o0 * o0 + o1 * o1 + o2 * o2
    free = hold - vmax * HOLD_TIME
    if not (free > 0.0 and d2 <= free * free):
        d = math.sqrt(d2)
        out = (v0 * o0 + v1 * o1 + v2 * o2) / d if d > 0.0 else 0.0
        cap = (hold - d) / HOLD_TIME
        cap = 0.0 if 0.0 > cap else cap
        if out > cap:
            k = (out - cap) / d
            v0, v1, v2 = v0 - k * o0, v1 - k * o1, v2 - k * o2
    s2 = v0 * v0 + v1 * v1 + v2 * v2
    if s2 > vmax * vmax:
        k = vmax / math.sqrt(s2)
        v0, v1, v2 = v0 * k, v1 * k, v2 * k
    return v0, v1, v2


@inline
def check(force: float, dev: float, speed: float, f_max: float, d_max: float, v_trip: float) -> int:
    """The monitor's force, path deviation and speed checks, in its order."""
    if not force <= f_max:
        return STOP_FORCE
    if not dev <= d_max:
        return STOP_DEVIATION
    if not speed <= v_trip:
        return STOP_SPEED
    return STOP_NONE


@kernel
def check_joints(
    qpos: np.ndarray, ai: np.ndarray, bounds: np.ndarray, n: int, per_tick: float
) -> tuple[int, float]:
    """The monitor's joint check (``SafetyMonitor._check_joints``): ``(STOP_JOINT, 0)`` for a
    joint out of its bounds (``bounds``: ``lower_0, upper_0, ...``; joint ``j``'s qpos address
    ``ai[n + j]``), else ``(STOP_NONE, ticks until the next check)``."""
    slack = math.inf
    for j in range(n):
        q = qpos[ai[n + j]]
        lo, hi = q - bounds[2 * j], bounds[2 * j + 1] - q
        room = hi if hi < lo else lo
        if not room >= 0.0:
            return STOP_JOINT, 0.0
        slack = room if room < slack else slack
    due = int(slack / per_tick)
    return STOP_NONE, float(max(1, min(JOINT_CHECK_MAX, due)))
