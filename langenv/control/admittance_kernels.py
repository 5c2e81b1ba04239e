"""The variable admittance compiled (:meth:`VariableAdmittance.step
<langenv.control.admittance.VariableAdmittance.step>`): the same operations in the same order,
bit-identical results (``tests/test_compiled_tick.py``)."""

from __future__ import annotations

import math

from langenv.kernels import kernel

__all__ = [
    "BAD_PACE",
    "BAD_PACE_END",
    "BAD_PACE_RATE",
    "BAD_TOTAL_FORCE",
    "BAD_VELOCITY",
    "OK",
    "step",
]

OK = 0
BAD_PACE, BAD_PACE_RATE, BAD_PACE_END, BAD_TOTAL_FORCE, BAD_VELOCITY = -2, -3, -4, -5, -6
"""Bad input: the Python step raises its error for it (``ConfigError``)."""


@kernel
def step(
    v0: float,
    v1: float,
    v2: float,
    f0: float,
    f1: float,
    f2: float,
    p: float,
    p_dot: float,
    dt: float,
    d_over_m: float,
    inv_d: float,
) -> tuple[int, float, float, float]:
    """``VariableAdmittance.step(v, f, p, p_dot, dt)``: ``(OK, v')``, or a code for bad input
    (``v`` unchanged)."""
    if not 0.0 < p < math.inf:
        return BAD_PACE, v0, v1, v2
    if not math.isfinite(p_dot):
        return BAD_PACE_RATE, v0, v1, v2
    p_end = p + p_dot * dt
    if not p_end > 0.0:
        return BAD_PACE_END, v0, v1, v2
    if not math.isfinite(f0 + f1 + f2):
        return BAD_TOTAL_FORCE, v0, v1, v2
    if not math.isfinite(v0 + v1 + v2):
        return BAD_VELOCITY, v0, v1, v2
    decay = math.exp(-d_over_m * (p + 0.5 * p_dot * dt) * dt)
    inv_p = 1.0 / p
    a0, a1, a2 = f0 * inv_d, f1 * inv_d, f2 * inv_d
    return (
        OK,
        p_end * (a0 + (v0 * inv_p - a0) * decay),
        p_end * (a1 + (v1 * inv_p - a1) * decay),
        p_end * (a2 + (v2 * inv_p - a2) * decay),
    )
