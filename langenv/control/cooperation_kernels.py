"""The cooperation filter compiled (:meth:`CooperationFilter.update
<langenv.control.cooperation.CooperationFilter.update>`, SPEC §1): the same operations in the
same order (``tests/test_compiled_tick.py``)."""

from __future__ import annotations

import math

from langenv.kernels import inline

__all__ = ["update"]


@inline
def update(
    r: float, m0: float, m1: float, m2: float, keep: float, inv_f_max: float
) -> tuple[float, float]:
    """One sample of the measured force ``m`` (N, after the deadband): ``(r, c)`` after it."""
    u = math.sqrt(m0 * m0 + m1 * m1 + m2 * m2) * inv_f_max
    if u > 1.0:
        u = 1.0
    r = keep * r + (1.0 - keep) * u
    return r, 1.0 - r
