"""The velocity command compiled (:mod:`langenv.control.command`): ``follow`` and ``cap_speed``,
the same operations in the same order (``tests/test_compiled_tick.py``)."""

from __future__ import annotations

import math

from langenv.kernels import inline

__all__ = ["cap_speed", "follow"]


@inline
def follow(
    c0: float, c1: float, c2: float, t0: float, t1: float, t2: float, dv_max: float
) -> tuple[float, float, float]:
    """:func:`~langenv.control.command.follow`: the command ``c`` moved towards ``t`` by at
    most ``dv_max``."""
    d0, d1, d2 = t0 - c0, t1 - c1, t2 - c2
    d2n = d0 * d0 + d1 * d1 + d2 * d2
    if not d2n <= dv_max * dv_max:
        k = dv_max / math.sqrt(d2n)
        return c0 + k * d0, c1 + k * d1, c2 + k * d2
    return t0, t1, t2


@inline
def cap_speed(v0: float, v1: float, v2: float, v_max: float) -> tuple[float, float, float]:
    """:func:`~langenv.control.command.cap_speed`: ``v`` scaled down to at most ``v_max``."""
    n2 = v0 * v0 + v1 * v1 + v2 * v2
    if not n2 <= v_max * v_max:
        k = v_max / math.sqrt(n2)
        return k * v0, k * v1, k * v2
    return v0, v1, v2
