"""CPython's ``math.hypot`` and ``math.dist`` (3-D), compiled, bit for bit.

CPython computes a vector norm with lossless scaling, Dekker's exact products and a
differential correction (``vector_norm`` in ``Modules/mathmodule.c``), so it can differ from
``sqrt(x*x + y*y + z*z)`` in the last bit; the safety monitor compares these against its limits.
"""

from __future__ import annotations

import math

from langenv.kernels import kernel

__all__ = ["dist3", "hypot3"]

_DBL_MIN = 2.2250738585072014e-308


@kernel
def _split(x: float) -> tuple[float, float]:
    t = x * 134217729.0  # 2**27 + 1
    hi = t - (t - x)
    return hi, x - hi


@kernel
def _mul(x: float, y: float) -> tuple[float, float]:
    xh, xl = _split(x)
    yh, yl = _split(y)
    p = xh * yh
    q = xh * yl + xl * yh
    z = p + q
    return z, p - z + q + xl * yl


@kernel
def _norm(v0: float, v1: float, v2: float) -> float:
    a0, a1, a2 = abs(v0), abs(v1), abs(v2)
    if math.isnan(a0) or math.isnan(a1) or math.isnan(a2):
        if math.isinf(a0) or math.isinf(a1) or math.isinf(a2):
            return math.inf
        return math.nan
    mx = a0
    if a1 > mx:
        mx = a1
    if a2 > mx:
        mx = a2
    if math.isinf(mx):
        return mx
    if mx == 0.0:
        return mx
    _, max_e = math.frexp(mx)
    if max_e < -1023:
        return _DBL_MIN * _norm(v0 / _DBL_MIN, v1 / _DBL_MIN, v2 / _DBL_MIN)
    scale = math.ldexp(1.0, -max_e)
    csum, frac1, frac2 = 1.0, 0.0, 0.0
    for x in (a0, a1, a2):
        x *= scale
        hi, lo = _mul(x, x)
        s = csum + hi
        frac2 += (csum - s) + hi
        csum = s
        frac1 += lo
    h = math.sqrt(csum - 1.0 + (frac1 + frac2))
    hi, lo = _mul(-h, h)
    s = csum + hi
    frac2 += (csum - s) + hi
    csum = s
    frac1 += lo
    x = csum - 1.0 + (frac1 + frac2)
    h += x / (2.0 * h)
    return h / scale


@kernel
def hypot3(x: float, y: float, z: float) -> float:
    """``math.hypot(x, y, z)``."""
    return _norm(x, y, z)


@kernel
def dist3(p0: float, p1: float, p2: float, q0: float, q1: float, q2: float) -> float:
    """``math.dist((p0, p1, p2), (q0, q1, q2))``."""
    return _norm(p0 - q0, p1 - q1, p2 - q2)
