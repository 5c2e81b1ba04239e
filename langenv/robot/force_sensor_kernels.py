"""The force sensor's deadband compiled (:meth:`ForceSensor.measure
<langenv.robot.force_sensor.ForceSensor.measure>` without its noise, which the compiled tick
takes as input): the same operations in the same order (``tests/test_compiled_tick.py``)."""

from __future__ import annotations

import math

from langenv.kernels import inline

__all__ = ["deadband"]


@inline
def deadband(m0: float, m1: float, m2: float, band: float) -> tuple[bool, float, float, float]:
    """``(ok, F~)``: the soft deadband of ``m`` (N); ``ok`` False for a non-finite force."""
    norm2 = m0 * m0 + m1 * m1 + m2 * m2
    if not norm2 < math.inf:
        return False, m0, m1, m2
    norm = math.sqrt(norm2)
    if norm <= band:
        return True, 0.0, 0.0, 0.0
    g = 1.0 - band / norm
    return True, m0 * g, m1 * g, m2 * g
