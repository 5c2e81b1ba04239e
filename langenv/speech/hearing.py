"""When the person hears each wording: its last word, as the voice says it.

:class:`Ear` follows a :class:`~langenv.speech.timeline.SpeechTimeline` tick by tick and reports
each clip (phrase or filler) once its last word is said, with the wording's intent
(:meth:`PhraseGraph.intent <langenv.speech.graph.PhraseGraph.intent>`): what a person who
listens (:class:`~langenv.users.Listener`) responds to. With the time-stretched voice a clip's
last word is said when the timeline reaches the clip's end; with the natural voice
(:mod:`langenv.speech.voice`) a clip that has a successor is said at ``max(a, SLOWEST)`` from its
start and the voice then waits, so its last word comes sooner when the pace is below
:data:`~langenv.speech.voice.SLOWEST`; a final clip follows ``a``.
"""

from __future__ import annotations

from langenv.speech.timeline import SpeechTimeline
from langenv.speech.voice import SLOWEST

__all__ = ["Ear"]


class Ear:
    """The wordings heard so far in a timeline's speech.

    Args:
        speech: The timeline (reset with it: :meth:`reset`).
    """

    __slots__ = ("_count", "_early", "_key", "_natural", "_said", "speech")

    def __init__(self, speech: SpeechTimeline) -> None:
        self.speech = speech
        self._natural = speech.graph.voice == "natural"
        self.reset()

    def reset(self) -> None:
        """Nothing heard yet (call with the timeline's reset)."""
        self._count = 0  # utterances of the timeline's history looked at
        self._early: set[int] = set()  # history places of clips heard before their clip ended
        self._key = -1  # the history place the clip being said will take
        self._said = 0.0  # base-pace seconds of it the natural voice has said

    def step(self, dt: float, a: float) -> list[tuple[float, str, str | None]]:
        """After the timeline stepped ``dt`` s at pace ``a``: ``(time, vertex, intent)`` of each
        clip whose last word was said in that step, in order."""
        sp = self.speech
        graph = sp.graph
        out: list[tuple[float, str, str | None]] = []
        hist = sp.history
        while self._count < len(hist):
            u = hist[self._count]
            if u.length is None and self._count not in self._early:
                out.append((u.t_end, u.phrase, graph.intent(u.phrase)))
            self._count += 1
        if not self._natural:
            return out
        v = sp.phrase
        if v is None or sp.in_pause or not graph.children(v):
            return out
        key = len(hist)
        if key in self._early:
            return out
        if key != self._key:  # a clip started in this step: the part of it said
            self._key, self._said = key, 0.0
            span = min(dt, sp.position / a) if a > 0.0 else 0.0
        else:
            span = dt
        rate = max(a, SLOWEST)
        self._said += rate * span
        dur = graph.duration[v]
        if self._said >= dur:
            self._early.add(key)
            out.append((sp.t - (self._said - dur) / rate, v, graph.intent(v)))
        return out
