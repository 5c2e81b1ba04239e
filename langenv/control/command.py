"""The velocity command sent to the robot: ``v_ref`` followed with a bounded acceleration.

A UR's ``speedL(v, a)`` moves the tool towards the commanded velocity ``v`` changing its velocity
at most at ``a`` m/s^2. The study's lab code sent the admittance's ``v_ref`` this way every cycle
and ended a session with ``speedL(0)``, so the hand lags ``v_ref`` whenever it changes faster than
``a`` (at a leg switch, where it reverses, or when a person suddenly lets go) and brakes to rest at
``a`` at the end: the V-shaped dips and the final ramps of the recorded hand speed
(``AdmittanceParams.max_acceleration``). Plain floats: it runs every tick.
"""

from __future__ import annotations

import math

import numpy as np

from langenv.layout import field_table

__all__ = ["COMMAND_SETTINGS", "COMMAND_STATE", "cap_speed", "follow"]

COMMAND_STATE = field_table(
    """
    v_cmd[3]         the velocity command sent in the last tick (m/s)
    was_moving:bool  the command was not zero before the last tick
    """
)
"""The command's state, declared for the compiled tick."""
COMMAND_SETTINGS = field_table(
    """
    max_acc  the command's acceleration limit (m/s^2)
    dv_max   its largest change per tick (m/s)
    """
)
"""The command's settings."""


def follow(current: np.ndarray, target: np.ndarray, dv_max: float) -> np.ndarray:
    """The command after one tick: ``current`` moved towards ``target`` by at most ``dv_max``.

    Args:
        current: Command velocity now, shape (3,), m/s.
        target: Velocity to follow (``v_ref``), shape (3,), m/s.
        dv_max: Largest change of the command in one tick (m/s): ``max_acceleration * dt``,
            ``inf`` to follow exactly.

    Returns:
        The new command, shape (3,), m/s (a new array).
    """
    c0, c1, c2 = current.tolist()
    t0, t1, t2 = target.tolist()
    d0, d1, d2 = t0 - c0, t1 - c1, t2 - c2
    d2n = d0 * d0 + d1 * d1 + d2 * d2
    if d2n <= dv_max * dv_max:
        return np.array((t0, t1, t2))
    k = dv_max / math.sqrt(d2n)
    return np.array((c0 + k * d0, c1 + k * d1, c2 + k * d2))


def cap_speed(v: np.ndarray, v_max: float) -> np.ndarray:
    """``v`` scaled down to at most ``v_max`` in norm (m/s); ``v`` itself when within it."""
    v0, v1, v2 = v.tolist()
    n2 = v0 * v0 + v1 * v1 + v2 * v2
    if n2 <= v_max * v_max:
        return v
    k = v_max / math.sqrt(n2)
    return np.array((k * v0, k * v1, k * v2))
