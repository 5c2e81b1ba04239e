"""Speech in step with every leg: when each leg's words start against when the motion enters it.

The metric (``SM_k``, ``legs_in_step``, ``sm_max_abs``) is defined in
:mod:`langenv.speech.in_step`, its one home (the learned phrase chooser's reward measures with it
too); this module measures an episode log with it. The graph records each vertex's leg and the
episode log each utterance's (:class:`~eval.episode.Utterance`), with the leg the motion is in at
each sample (:attr:`~eval.episode.EpisodeLog.leg`). For every leg after the first that the graph
has words for, a *boundary*:

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

from eval.episode import EpisodeLog
from langenv.speech.in_step import (
    SM_TOLERANCE,
    LegBoundary,
    boundaries,
    first_words,
    graph_legs,
    in_step,
    leg_entries,
)

__all__ = [
    "SM_TOLERANCE",
    "LegBoundary",
    "first_words",
    "graph_legs",
    "leg_boundaries",
    "leg_entries",
    "leg_metrics",
]


def leg_boundaries(log: EpisodeLog) -> tuple[LegBoundary, ...]:
    """The session's boundaries (module docstring), in the motion's order; empty when the log
    lacks the motion's legs or the graph is unmarked."""
    return boundaries(log.t, log.leg, log.leg_names, log.spoken_legs, log.utterances)


def leg_metrics(log: EpisodeLog) -> dict[str, float]:
    """``{"sm_max_abs": ..., "legs_in_step": ...}`` of a session (module docstring)."""
    return in_step(leg_boundaries(log))
