"""Dot products and norms of small vectors in one fixed order, the same on every CPU.

NumPy hands ``a.dot(b)``, ``a @ b`` and ``np.linalg.norm(a)`` of float64 vectors to the BLAS
library it ships (OpenBLAS), which picks a kernel for the CPU it runs on; the kernels sum in
different orders (the AVX-512 one differs in the last bit from the AVX2 one even for three
entries), so the same episode would not give the same numbers on another machine. These
functions sum ``a[0] b[0] + a[1] b[1] + ...`` left to right in plain IEEE arithmetic, which is
also the order the compiled kernels (:mod:`langenv.kernels`) write out, so the Python reference
and the kernels agree to the bit on any x86-64 CPU.

They read a NumPy array through ``tolist()`` and check nothing (the callers validate).
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

__all__ = ["dot", "norm", "sumsq"]


def dot(a: NDArray[np.float64], b: NDArray[np.float64]) -> float:
    """``sum_i a[i] b[i]``, left to right. ``a``, ``b``: (n,) float64."""
    s = 0.0
    for x, y in zip(a.tolist(), b.tolist(), strict=True):
        s += x * y
    return s


def sumsq(a: NDArray[np.float64]) -> float:
    """``sum_i a[i]^2``, left to right. ``a``: (n,) float64."""
    s = 0.0
    for x in a.tolist():
        s += x * x
    return s


def norm(a: NDArray[np.float64]) -> float:
    """Euclidean norm ``sqrt(sumsq(a))``. ``a``: (n,) float64."""
    return math.sqrt(sumsq(a))
