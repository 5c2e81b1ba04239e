"""The phrase graph's rules compiled (:class:`~langenv.speech.graph.PhraseGraph`), choosing
with the paper's rule (:func:`langenv.speech.choice_kernels.nearest`): the pause rule
(:meth:`~langenv.speech.graph.PhraseGraph.pause_length`) and the speech ETC ``t_a``
(:meth:`~langenv.speech.graph.PhraseGraph.eta`), each planned to the end of a segment
(:mod:`langenv.speech.legs`).

The graph as arrays (:meth:`PhraseGraph.packed <langenv.speech.graph.PhraseGraph.packed>`):
``mid`` (n: each vertex's ``(t_min + t_max) / 2``), ``slot`` (n, 3: the nominal slot, its
minimum and maximum, which differ for a pause only), the children's offsets ``kid_ptr``
(n + 1) and indexes ``kids``, in the graph's order. The same operations in the same order as
the Python methods, comparison for comparison (``tests/test_graph_pauses.py``,
``tests/test_repeat.py``).
"""

from __future__ import annotations

import numpy as np

from langenv.kernels import kernel
from langenv.speech.choice_kernels import nearest
from langenv.speech.legs_kernels import gate, horizon, segment

__all__ = ["eta", "fill"]


@kernel
def fill(
    v: int,
    left: float,
    mid: np.ndarray,
    slot: np.ndarray,
    kid_ptr: np.ndarray,
    kids: np.ndarray,
    lg: np.ndarray,
) -> float:
    """:meth:`PhraseGraph.pause_length <langenv.speech.graph.PhraseGraph.pause_length>` of the
    pause of index ``v`` (the same operations in the same order; the plan stops at a gate:
    ``lg``, :mod:`langenv.speech.legs_kernels`)."""
    y = left - slot[v, 0]
    rest = 0.0
    lo, hi = kid_ptr[v], kid_ptr[v + 1]
    if gate(lg, v):
        hi = lo
    while hi > lo:
        w = nearest(lo, hi, kids, mid, y)
        rest += slot[w, 0]
        y -= slot[w, 0]
        lo, hi = kid_ptr[w], kid_ptr[w + 1]
        if gate(lg, w):
            hi = lo
    length = left - rest
    s_lo, s_hi = slot[v, 1], slot[v, 2]
    return s_lo if length < s_lo else (s_hi if length > s_hi else length)


@kernel
def eta(
    u: int,
    remaining: float,
    t_x: float,
    t_leg: float,
    leg: int,
    last: int,
    mid: np.ndarray,
    slot: np.ndarray,
    kid_ptr: np.ndarray,
    kids: np.ndarray,
    lg: np.ndarray,
) -> float:
    """:meth:`PhraseGraph.eta <langenv.speech.graph.PhraseGraph.eta>` of vertex index ``u`` to
    the end of segment ``last``, the motion's times to the segments' ends from ``t_x``, the
    current leg's ``t_leg`` and ``leg`` (:func:`langenv.speech.legs_kernels.horizon`)."""
    total = remaining
    cur = -1
    left = 0.0
    lo, hi = kid_ptr[u], kid_ptr[u + 1]
    while hi > lo:
        j = segment(lg, kids[lo])
        if j > last:
            break
        if j != cur:
            cur = j
            left = horizon(lg, j, t_x, t_leg, leg) - total
        v = nearest(lo, hi, kids, mid, left)
        if slot[v, 1] == slot[v, 2]:
            length = slot[v, 0]
        else:
            length = fill(v, left, mid, slot, kid_ptr, kids, lg)
        total += length
        left -= length
        lo, hi = kid_ptr[v], kid_ptr[v + 1]
    return total
