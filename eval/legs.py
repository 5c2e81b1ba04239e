"""Speech in step with every leg: when each leg's words start against when the motion enters it.

A script marks which leg of the exercise each line speaks about (``@leg NAME``,
:mod:`langenv.speech.author`); the phrase graph records each vertex's leg and the episode log
each utterance's (:class:`~eval.episode.Utterance`), with the leg the motion is in at each
sample (:attr:`~eval.episode.EpisodeLog.leg`). For every leg after the first that the graph has
words for, a *boundary*:

* ``t_enter``: the first sample at which the motion is in that leg (the guide's leg index
  switching; NaN when the motion never got there);
* ``t_words``: the start of the first words said for that leg: the first utterance of a phrase
  (not a filler, not a pause) whose vertex is marked with it (NaN when none was said);
* ``SM = t_words - t_enter`` (s): positive when the words come after the motion turned, NaN
  when either is missing.

Per session, ``legs_in_step`` is the share of boundaries with ``|SM| <= SM_TOLERANCE`` (a
boundary whose words were never said is not in step) and ``sm_max_abs`` the largest ``|SM|``
of the boundaries whose words were said (NaN when none was). Both are NaN for an unmarked graph,
a log without the motion's legs, or an exercise of one leg.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from eval.episode import EpisodeLog, Utterance

__all__ = [
    "SM_TOLERANCE",
    "LegBoundary",
    "first_words",
    "graph_legs",
    "leg_boundaries",
    "leg_entries",
    "leg_metrics",
]

SM_TOLERANCE = 1.0
"""A leg's words are in step with it when they start within this many seconds of it (s): the
end headline's tolerance for |AM|."""


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


def first_words(utterances: Sequence[Utterance], legs: Sequence[str]) -> dict[str, float]:
    """The start (s) of the first phrase said for each of ``legs`` (fillers and pauses left
    out); NaN for a leg none of whose phrases was said."""
    out = dict.fromkeys(legs, math.nan)
    for u in utterances:
        if u.leg in out and math.isnan(out[u.leg]) and not u.is_pause and not u.filler:
            out[u.leg] = u.t_start
    return out


def leg_boundaries(log: EpisodeLog) -> tuple[LegBoundary, ...]:
    """The session's boundaries (module docstring), in the motion's order; empty when the log
    lacks the motion's legs or the graph is unmarked."""
    if log.leg is None or not log.leg_names or not log.spoken_legs:
        return ()
    names = [(k, n) for k, n in enumerate(log.leg_names) if k > 0 and n in log.spoken_legs]
    entries = leg_entries(log.t, log.leg, len(log.leg_names))
    words = first_words(log.utterances, [n for _, n in names])
    return tuple(LegBoundary(n, k, float(entries[k]), words[n]) for k, n in names)


def leg_metrics(log: EpisodeLog) -> dict[str, float]:
    """``{"sm_max_abs": ..., "legs_in_step": ...}`` of a session (module docstring)."""
    found = leg_boundaries(log)
    if not found:
        return {"sm_max_abs": math.nan, "legs_in_step": math.nan}
    said = [abs(b.sm) for b in found if not math.isnan(b.sm)]
    return {
        "sm_max_abs": max(said) if said else math.nan,
        "legs_in_step": sum(b.in_step for b in found) / len(found),
    }


def graph_legs(graph: Any) -> tuple[dict[str, str | None], tuple[str, ...]]:
    """What an episode log keeps of a phrase graph's legs
    (:class:`~langenv.speech.graph.PhraseGraph`): each vertex's leg, and the legs it has
    phrases for (:attr:`EpisodeLog.spoken_legs <eval.episode.EpisodeLog.spoken_legs>`), in
    script order; ``({}, ())`` for an unmarked graph."""
    if not graph.legs:
        return {}, ()
    leg_of = {u: graph.leg(u) for u in graph.phrases}
    worded = {leg_of[u] for u in graph.phrases if graph.kind(u) == "phrase"}
    return leg_of, tuple(n for n in graph.legs if n in worded)
