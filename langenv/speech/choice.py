"""The paper's phrase choice: the one home of the rule and of the action that steers it.

At a phrase boundary the next phrase is the child ``v`` whose middle length ``(t_min +
t_max)(v) / 2`` is nearest the motion's time to go ``t_x``, the first listed on a tie
(:func:`nearest`; :meth:`PhraseGraph.choose <langenv.speech.graph.PhraseGraph.choose>`, the pause
rule and the speech ETC ``t_a`` plan with it). In the env's "target" choice mode a policy moves
the target: the action's next-phrase value ``u`` in [-1, 1] asks for ``t_x 2^(CHOICE_OCTAVES u)``
(:func:`duration_factor`; also the pause rule's target while the speech pauses), and a policy
that wants a duration ratio sends :func:`choice_action` of it. The compiled twin is
:mod:`langenv.speech.choice_kernels` (``tests/test_law_homes.py``).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

__all__ = ["CHOICE_OCTAVES", "choice_action", "duration_factor", "nearest"]

CHOICE_OCTAVES = 2.0
"""Octaves of the target-duration action per unit: ``u`` in [-1, 1] spans ``t_x 2^(+-2)``."""


def nearest(kids: Sequence[str], mid: Mapping[str, float], x: float) -> str:
    """The paper's choice: the first of ``kids`` (non-empty) whose ``mid`` is nearest ``x``
    (a NaN distance never wins: with a NaN ``x``, the first)."""
    best = kids[0]
    best_err = abs(x - mid[best])
    for v in kids[1:]:
        err = abs(x - mid[v])
        if err < best_err:
            best, best_err = v, err
    return best


def duration_factor(u: float) -> float:
    """The target duration over ``t_x`` that the next-phrase action ``u`` asks for:
    ``2^(CHOICE_OCTAVES u)``."""
    return 2.0 ** (CHOICE_OCTAVES * u)


def choice_action(ratio: float) -> float:
    """The next-phrase action that asks for ``ratio`` times ``t_x`` (> 0): the inverse of
    :func:`duration_factor`, clipped to [-1, 1]."""
    u = math.log2(ratio) / CHOICE_OCTAVES
    return min(1.0, max(-1.0, u))
