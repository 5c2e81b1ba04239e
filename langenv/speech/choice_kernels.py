"""The phrase choice compiled (:mod:`langenv.speech.choice`): the same comparisons in the same
order (``tests/test_law_homes.py``); the pause rule and ``t_a`` compiled
(:mod:`langenv.speech.graph_kernels`) choose with it."""

from __future__ import annotations

import numpy as np

from langenv.kernels import inline

__all__ = ["nearest"]


@inline
def nearest(lo: int, hi: int, kids: np.ndarray, mid: np.ndarray, x: float) -> int:
    """:func:`langenv.speech.choice.nearest` among ``kids[lo:hi]`` (non-empty; vertex indexes,
    ``mid`` by index): the first whose ``mid`` is nearest ``x``."""
    best = kids[lo]
    best_err = abs(x - mid[best])
    for j in range(lo + 1, hi):
        v = kids[j]
        err = abs(x - mid[v])
        if err < best_err:
            best, best_err = v, err
    return int(best)
