"""The compiled speech ETC and pause rule of an unmarked graph, callable from the tests (one
segment, no gate: ``langenv/speech/legs.py``), indexed as ``tuple(g.phrases)``."""

from __future__ import annotations

import numpy as np

from langenv.speech.graph import PhraseGraph
from langenv.speech.graph_kernels import eta as compiled_eta
from langenv.speech.graph_kernels import fill as compiled_fill
from langenv.speech.legs import LegPlan


def one_leg(g: PhraseGraph) -> np.ndarray:
    """The compiled legs of an unmarked graph (one segment, no gate)."""
    return LegPlan.whole(1).packed([0] * len(g.order), [False] * len(g.order))


def c_eta(g: PhraseGraph, i: int, remaining: float, t_x: float) -> float:
    """The compiled eta of vertex index ``i`` (of ``g.phrases``) of an unmarked graph."""
    mid, slot, kid_ptr, kids = g.packed(tuple(g.phrases))
    return float(compiled_eta(i, remaining, t_x, t_x, 0, 0, mid, slot, kid_ptr, kids, one_leg(g)))


def c_fill(g: PhraseGraph, i: int, target: float) -> float:
    """The compiled pause rule of vertex index ``i`` of an unmarked graph."""
    mid, slot, kid_ptr, kids = g.packed(tuple(g.phrases))
    return float(compiled_fill(i, target, mid, slot, kid_ptr, kids, one_leg(g)))
