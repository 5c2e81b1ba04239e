"""The synthetic user's noise filter, compiled: a first-order recursion over a whole force table.

:func:`ar1` is :func:`langenv.users.synthetic.ar1_filter`'s recursion (``scipy.signal.lfilter([1],
[1, -a], x)`` to the bit: one multiplication and one addition per sample, in order). A
:class:`~langenv.users.SyntheticUser` filters a sample per 10 ms of its 120 s horizon at every
reset; in Python that loop alone cost about a millisecond per episode.
"""

from __future__ import annotations

import numpy as np

from langenv.kernels import kernel

__all__ = ["ar1"]


@kernel
def ar1(x: np.ndarray, a: float, out: np.ndarray) -> None:
    """``out[0] = x[0]``, ``out[n] = x[n] + a out[n-1]`` (``x``, ``out``: float64 (n,))."""
    y = 0.0
    for i in range(x.shape[0]):
        y = x[i] + a * y
        out[i] = y
