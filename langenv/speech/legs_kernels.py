"""The legs' horizons compiled (:class:`~langenv.speech.legs.LegPlan`), and each vertex's
segment and gate flag, read from the packed plan ``lg`` (:meth:`LegPlan.packed
<langenv.speech.legs.LegPlan.packed>`: ``[S, n, last_leg (S), rest (S), seg (n), gate (n)]``).
The same operations in the same order as the Python methods (``tests/test_legs.py``)."""

from __future__ import annotations

import numpy as np

from langenv.kernels import inline

__all__ = ["gate", "horizon", "motion_segment", "segment", "segments"]


@inline
def segments(lg: np.ndarray) -> int:
    """Number of segments."""
    return int(lg[0])


@inline
def segment(lg: np.ndarray, v: int) -> int:
    """The segment of vertex index ``v``."""
    s = int(lg[0])
    return int(lg[2 + 2 * s + v])


@inline
def gate(lg: np.ndarray, v: int) -> bool:
    """Whether vertex index ``v`` is a gate (its children begin the next segment)."""
    s, n = int(lg[0]), int(lg[1])
    return lg[2 + 2 * s + n + v] != 0.0


@inline
def motion_segment(lg: np.ndarray, leg: int) -> int:
    """:meth:`LegPlan.motion_segment <langenv.speech.legs.LegPlan.motion_segment>`."""
    s = int(lg[0])
    for j in range(s):
        if leg <= lg[2 + j]:
            return j
    return s - 1


@inline
def horizon(lg: np.ndarray, j: int, t_x: float, t_leg: float, leg: int) -> float:
    """:meth:`LegPlan.horizon <langenv.speech.legs.LegPlan.horizon>` of segment ``j``."""
    s = int(lg[0])
    if j == s - 1:
        return t_x
    last = lg[2 + j]
    if leg > last:
        return 0.0
    if leg == last:
        return t_leg
    rest = t_x - lg[2 + s + j]
    return rest if rest > t_leg else t_leg
