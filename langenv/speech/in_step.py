"""Speech in step with every leg, measured: when each leg's words start against when the motion
enters the leg.

A script marks which leg of the exercise each line speaks about (``@leg NAME``,
:mod:`langenv.speech.author`); the phrase graph records each vertex's leg, and the env says the
leg the motion is in (``info["leg"]``: its index in the exercise's legs, their number once the
last is done). For every leg after the first that the graph has words for, a *boundary*:

* ``t_enter``: the first sample at which the motion is in that leg (NaN when the motion never
  got there);
* ``t_words``: the start of the first words said for that leg: the first utterance of a phrase
  (not a filler, not a pause) whose vertex is marked with it (NaN when none was said);
* ``SM = t_words - t_enter`` (s): positive when the words come after the motion turned, NaN
  when either is missing.

Per session (:func:`in_step`), ``legs_in_step`` is the share of boundaries with
``|SM| <= SM_TOLERANCE`` (a boundary whose words were never said is not in step) and
``sm_max_abs`` the largest ``|SM|`` of the boundaries whose words were said (NaN when none was).
Both are NaN without a boundary: an unmarked graph, no leg trace, an exercise of one leg.

This module is the metric's one home: the evaluation (:mod:`eval.legs`, on an episode log) and
the learned phrase chooser's reward (:class:`train.choices.ChoicePoints`, on the env's trace and
the speech timeline) both measure with it.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np

__all__ = [
    "SM_TOLERANCE",
    "LegBoundary",
    "Said",
    "SaidWords",
    "boundaries",
    "first_words",
    "graph_legs",
    "in_step",
    "leg_entries",
    "said_words",
]

SM_TOLERANCE = 1.0
"""A leg's words are in step with it when they start within this many seconds of it (s): the
end headline's tolerance for |AM|."""


class Said(Protocol):
    """What :func:`first_words` reads of an utterance (``eval.episode.Utterance`` has it)."""

    @property
    def t_start(self) -> float: ...
    @property
    def leg(self) -> str: ...
    @property
    def is_pause(self) -> bool: ...
    @property
    def filler(self) -> bool: ...


@dataclass(frozen=True)
class SaidWords:
    """An utterance of the speech timeline with what the graph says of its vertex
    (:func:`said_words`).

    Attributes:
        t_start: When it started (s).
        leg: The leg its vertex speaks about (empty in an unmarked graph).
        is_pause: A pause vertex's silence.
        filler: A filler clip.
    """

    t_start: float
    leg: str
    is_pause: bool
    filler: bool


@dataclass(frozen=True)
class LegBoundary:
    """One leg's boundary in a session.

    Attributes:
        leg: The leg's name.
        index: Its index in the motion's legs (>= 1).
        t_enter: When the motion entered it (s), NaN if it never did.
        t_words: When its first words started (s), NaN if none were said.
    """

    leg: str
    index: int
    t_enter: float
    t_words: float

    @property
    def sm(self) -> float:
        """``t_words - t_enter`` (s); NaN when either is missing."""
        return self.t_words - self.t_enter

    @property
    def in_step(self) -> bool:
        """Whether the words started within :data:`SM_TOLERANCE` of the leg (False for NaN)."""
        return bool(abs(self.sm) <= SM_TOLERANCE)


def leg_entries(t: np.ndarray, leg: np.ndarray, n_legs: int) -> np.ndarray:
    """When the motion entered each of ``n_legs`` legs: the time of the first sample at which
    its leg index is at least ``k`` (leg 0: ``t[0]``); NaN for a leg it never reached, shape
    ``(n_legs,)``."""
    out = np.full(n_legs, math.nan)
    for k in range(n_legs):
        hit = np.flatnonzero(leg >= k)
        if hit.size:
            out[k] = float(t[hit[0]])
    return out


def first_words(utterances: Sequence[Said], legs: Sequence[str]) -> dict[str, float]:
    """The start (s) of the first phrase said for each of ``legs`` (fillers and pauses left
    out); NaN for a leg none of whose phrases was said."""
    out = dict.fromkeys(legs, math.nan)
    for u in utterances:
        if u.leg in out and math.isnan(out[u.leg]) and not u.is_pause and not u.filler:
            out[u.leg] = u.t_start
    return out


def boundaries(
    t: np.ndarray,
    leg: np.ndarray | None,
    leg_names: Sequence[str],
    spoken_legs: Sequence[str],
    utterances: Sequence[Said],
) -> tuple[LegBoundary, ...]:
    """A session's boundaries (module docstring), in the motion's order.

    Args:
        t: Sample times (s), shape ``(n,)``.
        leg: The motion's leg index at those times (``info["leg"]``), shape ``(n,)``; None
            when unknown.
        leg_names: The motion's legs, in order (the exercise's); empty when unknown.
        spoken_legs: The legs the graph has words for (:func:`graph_legs`); empty for an
            unmarked graph.
        utterances: What was said, in order, each with its leg (:class:`Said`).

    Returns:
        One :class:`LegBoundary` per leg after the first that the graph has words for; empty
        when ``leg``, ``leg_names`` or ``spoken_legs`` is missing.
    """
    if leg is None or not leg_names or not spoken_legs:
        return ()
    names = [(k, n) for k, n in enumerate(leg_names) if k > 0 and n in spoken_legs]
    entries = leg_entries(t, leg, len(leg_names))
    words = first_words(utterances, [n for _, n in names])
    return tuple(LegBoundary(n, k, float(entries[k]), words[n]) for k, n in names)


def in_step(found: Sequence[LegBoundary]) -> dict[str, float]:
    """``{"sm_max_abs": ..., "legs_in_step": ...}`` of a session's boundaries (module
    docstring; both NaN without a boundary)."""
    if not found:
        return {"sm_max_abs": math.nan, "legs_in_step": math.nan}
    said = [abs(b.sm) for b in found if not math.isnan(b.sm)]
    return {
        "sm_max_abs": max(said) if said else math.nan,
        "legs_in_step": sum(b.in_step for b in found) / len(found),
    }


def graph_legs(graph: Any) -> tuple[dict[str, str | None], tuple[str, ...]]:
    """What a session keeps of a phrase graph's legs
    (:class:`~langenv.speech.graph.PhraseGraph`): each vertex's leg, and the legs it has
    phrases for, in script order; ``({}, ())`` for an unmarked graph."""
    if not graph.legs:
        return {}, ()
    leg_of = {u: graph.leg(u) for u in graph.phrases}
    worded = {leg_of[u] for u in graph.phrases if graph.kind(u) == "phrase"}
    return leg_of, tuple(n for n in graph.legs if n in worded)


def said_words(utterances: Sequence[Any], graph: Any) -> list[SaidWords]:
    """The speech timeline's utterances (``SpeechTimeline.utterances()``: ``phrase``,
    ``t_start``, ``length``, None for a clip) with their vertex's leg and kind in ``graph``."""
    leg_of, _ = graph_legs(graph)
    return [
        SaidWords(
            float(u.t_start),
            leg_of.get(str(u.phrase)) or "",
            u.length is not None,
            str(u.phrase) in graph.fillers,
        )
        for u in utterances
    ]
