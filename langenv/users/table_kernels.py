"""A tabulated user's force compiled: :func:`~langenv.users.base.sample_table` and
:func:`~langenv.users.base.against_motion`, the same operations in the same order
(``tests/test_compiled_steps.py``)."""

from __future__ import annotations

import math

import numpy as np

from langenv.kernels import inline, kernel

__all__ = ["against_motion", "magnitude"]


@kernel
def magnitude(table: np.ndarray, step: float, t: float) -> float:
    """:func:`~langenv.users.base.sample_table` (``t >= 0``)."""
    x = t / step
    k = int(x)
    last = table.shape[0] - 1
    if k >= last:
        return table[last] if x == last else 0.0
    f0 = table[k]
    f1 = table[k + 1]
    w = x - k
    if f0 == 0.0 or f1 == 0.0:
        return f0 if w < 0.5 else f1
    return f0 + w * (f1 - f0)


@inline
def against_motion(mag: float, b0: float, b1: float, b2: float) -> tuple[bool, float, float, float]:
    """:func:`~langenv.users.base.against_motion` of ``mag`` (N, != 0) along ``b``: ``(ok,
    force)``; ``ok`` False where the Python function raises (a zero or non-finite ``b``)."""
    norm = math.sqrt(b0 * b0 + b1 * b1 + b2 * b2)
    if not (math.isfinite(norm) and norm > 1e-12):
        return False, 0.0, 0.0, 0.0
    k = -mag / norm
    return True, b0 * k, b1 * k, b2 * k
