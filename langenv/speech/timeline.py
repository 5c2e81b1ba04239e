"""The speech timeline: where the robot is in its speech, played at a varying audio pace.

Speech starts with the graph's ``start`` phrase at ``reset``. Playback content advances at the
audio pace ``a`` (``a`` seconds of base-pace content per second). Each vertex occupies a *slot*:
a phrase's or filler's clip, then (unless it is final) the graph's pause, which also elapses at
pace ``a``. A pause vertex's slot is silence whose length the graph's rule
(:meth:`PhraseGraph.pause_length <langenv.speech.graph.PhraseGraph.pause_length>`) chooses within
its bounds for a *target*, the speech time wanted from now (the caller's, else ``t_x``): when the
pause is entered, and again at every step while it lasts (never below what has elapsed), as a
person who waits for the arm goes on waiting while it is slow. When a slot ends — this is the
*phrase boundary* — the next vertex starts at once: the caller's choice if it gave one, else the
graph's rule with the motion ETC ``t_x`` the caller passed. Speech is over when the clip of a
final phrase ends.

Stepping costs a few additions per tick except at the (rare) clip and slot ends, so it can run
inside a 500 Hz control loop.
"""

from __future__ import annotations

import bisect
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

from langenv.errors import ActionError, ConfigError
from langenv.layout import field_table
from langenv.speech.graph import PhraseGraph

__all__ = ["TIMELINE_STATE", "Choice", "PauseTarget", "SpeechTimeline", "Utterance"]

TIMELINE_STATE = field_table(
    """
    speech_pos     base-pace seconds into the current vertex's slot
    speech_t       time since the timeline's reset (s)
    speech_a       the audio pace of the last step
    mark           the content position where the next boundary falls (s at a = 1)
    phrase:index   the current vertex (its index; -1 once speech is over)
    slot           the current vertex's slot length (a pause: as planned now; s at a = 1)
    in_pause:bool  in the silence after a clip, or a pause vertex
    """
)
"""The timeline's state inside a vertex, declared for the compiled ticks (which stop before a
boundary: the choice and the history are Python's)."""

Choice = str | Callable[[tuple[str, ...]], str] | None
"""The next phrase at a boundary: a phrase id, a function of the candidate ids, or None."""

Horizons = float | Sequence[float] | None
"""The motion's time to completion (s), or to the end of each of the graph's segments
(:mod:`langenv.speech.legs`), for the rules; None: none given."""


class _SegmentTargets:
    """The pause rule's target of each pause: its segment's horizon times a factor (a gate
    waits for its leg whatever the factor)."""

    __slots__ = ("factor", "graph", "horizons")

    def __init__(self, graph: PhraseGraph, horizons: Sequence[float], factor: float) -> None:
        self.graph, self.horizons, self.factor = graph, horizons, factor

    def of(self, v: str) -> float:
        h = self.horizons[self.graph.segment(v)]
        return h if self.graph.is_gate(v) else h * self.factor


PauseTarget = float | _SegmentTargets | None
"""The speech time (s) wanted from the start of a step, for the pause rule; None: ``t_x``."""


@dataclass(frozen=True)
class Utterance:
    """One vertex said: a phrase's or filler's clip, or a pause vertex's silence.

    Attributes:
        phrase: Vertex id.
        t_start: Time its clip (or silence) started (s since the timeline's reset).
        t_end: Time its clip ended (s), the graph's pause after it excluded.
        length: A pause vertex's length at a = 1 (s; so far, while it lasts); None for a clip.
    """

    phrase: str
    t_start: float
    t_end: float
    length: float | None = None

    @property
    def duration(self) -> float:
        """How long it played (s)."""
        return self.t_end - self.t_start


class SpeechTimeline:
    """Playback position in a phrase graph's speech at a time-varying audio pace.

    Args:
        graph: The phrase graph to speak.

    Attributes (read-only properties): ``t``, ``phrase``, ``in_pause``, ``done``, ``position``,
    ``remaining_in_phrase``, ``remaining_audio``, ``fraction_said``, ``candidates``, ``history``,
    ``path``, ``t_end``, ``content_time``, ``a``.
    """

    __slots__ = (
        "_a",
        "_children",
        "_content_done",
        "_cur_slot",
        "_done",
        "_dur",
        "_elastic",
        "_graph",
        "_history",
        "_in_pause",
        "_mark",
        "_path",
        "_pause_lengths",
        "_pauses",
        "_phrase",
        "_pos",
        "_slot",
        "_t",
        "_t_end",
        "_t_start",
    )

    def __init__(self, graph: PhraseGraph) -> None:
        if not isinstance(graph, PhraseGraph):
            raise ConfigError(f"SpeechTimeline: graph must be a PhraseGraph, got {graph!r}")
        self._graph = graph
        self._dur = dict(graph.duration)
        self._slot = {u: graph.slot(u) for u in graph.phrases}
        self._children = {u: graph.children(u) for u in graph.phrases}
        self._pauses = graph.pauses
        self.reset()

    def reset(self) -> None:
        """Back to the start of the speech, at time 0."""
        start = self._graph.start
        self._t = 0.0
        self._a = 1.0
        self._phrase: str | None = start
        self._pos = 0.0  # base-pace seconds into the current phrase's slot
        self._in_pause = False
        self._done = False
        self._t_start = 0.0
        self._t_end: float | None = None
        self._content_done = 0.0  # base-pace seconds of finished slots
        self._history: list[Utterance] = []
        self._path: list[str] = [start]
        self._pause_lengths: list[float] = []
        self._cur_slot = self._slot[start]  # the current vertex's slot (a pause: its length)
        self._elastic = False  # in a pause vertex whose length is still open
        self._mark = self._dur[start]  # next content position where something happens

    # ------------------------------------------------------------------ stepping
    def step(
        self,
        dt: float,
        a: float,
        choice: Choice = None,
        t_x: Horizons = None,
        pause: PauseTarget = None,
        pause_factor: float | None = None,
    ) -> None:
        """Advance by ``dt`` seconds at audio pace ``a``.

        If the current vertex's slot ends during the step, the next vertex is ``choice`` (an id,
        or ``choice(candidates)`` when it is callable, evaluated only then), else
        ``graph.choose(phrase, t_x')`` with ``t_x'`` the given ``t_x`` minus the time from the
        start of the step to the boundary. A vertex with a single child needs neither (``choice``
        is then not consulted, so a callable is only called when there is a real choice). A second
        boundary inside the same step (only with slots shorter than ``a * dt``) calls a callable
        ``choice`` again, else uses the rule, else the first child; but a gate between legs with a
        choice after it, entered when its leg has begun, ends with the step: its leg's first
        words are chosen at the next step, by the next ``choice``. A pause entered takes the
        length ``graph.pause_length(id, target')`` with ``target'`` the target (``pause``, else
        ``t_x``) minus the time to the boundary (at a second boundary without either: the
        pause's minimum); while it lasts, each step sets it again to
        ``graph.pause_length(id, elapsed + target)``, never below what has elapsed. After the
        speech is over, only the time advances.

        Args:
            dt: Step length (s, > 0).
            a: Audio pace over the step (>= 0; 1 is the recorded pace).
            choice: Next vertex at a boundary (see above).
            t_x: Motion time to completion at the start of the step (s), for the rules; for a
                graph that speaks about several legs, the motion's time to the end of each
                segment (:meth:`LegPlan.horizons <langenv.speech.legs.LegPlan.horizons>`): a
                choice compares with its children's segment's, a pause with its own.
            pause: Speech time wanted from the start of the step (s), for the pause rule; None:
                ``t_x`` (the pause's segment's), times ``pause_factor`` when given, except
                for a gate between legs, which always waits for its leg.
            pause_factor: See ``pause``.

        Raises:
            ActionError: naming the argument, for a non-finite or out-of-range ``dt``/``a``, a
                choice that is not a child of the ending vertex, a non-finite target, or a
                boundary with several candidates (or a pause to enter) and neither ``choice``
                (``pause``) nor ``t_x``. The timeline is unchanged then.
        """
        if not 0.0 < dt < math.inf:
            raise ActionError(f"SpeechTimeline.step: dt must be finite and > 0, got {dt!r}")
        if not 0.0 <= a < math.inf:
            raise ActionError(f"SpeechTimeline.step: a must be finite and >= 0, got {a!r}")
        self._a = a
        if self._done:
            self._t += dt
            return
        adv = a * dt
        if pause is None and t_x is not None:
            pause = self._factored(t_x, pause_factor)
        if self._pos + adv < self._mark:  # the common case: nothing happens in this tick
            self._pos += adv
            self._t += dt
            if self._elastic:
                target = self._pause_target(self._phrase, pause, None)
                if target is not None:
                    self._replan(target)
            return
        self._advance(dt, a, adv, choice, t_x, pause)

    def reopen(
        self, v: str, t: float, t_x: Horizons = None, pause_factor: float | None = None
    ) -> None:
        """Go on speaking from the vertex ``v`` at time ``t`` (s) after the speech ended
        (:func:`~langenv.speech.repeat.reopen_vertex`: the motion went back); the next
        :meth:`step` goes on from there. A pause ``v`` is entered as :meth:`step` enters one
        (``t_x`` and ``pause_factor`` as there; without them, its minimum). The utterances so
        far stay; :attr:`t_end` is None again.

        Raises:
            ConfigError: if the speech has not ended, ``t`` is before the timeline's time, or
                ``v`` is not a vertex.
        """
        if not self._done:
            raise ConfigError("SpeechTimeline.reopen: the speech has not ended")
        if not t >= self._t:
            raise ConfigError(f"SpeechTimeline.reopen: t must be >= {self._t}, got {t!r}")
        if v not in self._dur:
            raise ConfigError(f"SpeechTimeline.reopen: {v!r} is not a vertex of the graph")
        length = 0.0
        if v in self._pauses:
            pause = None if t_x is None else self._factored(t_x, pause_factor)
            length = self._pause_length(v, pause, t_x, 0.0, True)
        self._done = False
        self._t_end = None
        self._t = float(t)
        self._enter(v, self._t, length)
        self._mark = self._cur_slot if self._in_pause else self._dur[v]

    def _factored(self, t_x: float | Sequence[float], factor: float | None) -> PauseTarget:
        """The pause rule's targets from the horizons: each segment's times ``factor`` (the
        gates' untouched), as a mapping from vertex to target, or one number for one segment."""
        if factor is None:
            return t_x if isinstance(t_x, int | float) else _SegmentTargets(self._graph, t_x, 1.0)
        if isinstance(t_x, int | float):
            return t_x * factor
        return _SegmentTargets(self._graph, t_x, factor)

    def _pause_target(self, v: str | None, pause: PauseTarget, t_x: Horizons) -> float | None:
        """The pause rule's target for the pause ``v`` (see :meth:`step`)."""
        if isinstance(pause, _SegmentTargets):
            assert v is not None
            return pause.of(v)
        if pause is not None:
            return pause
        if t_x is None or isinstance(t_x, int | float):
            return t_x
        assert v is not None
        return t_x[self._graph.segment(v)]

    def _replan(self, target: float) -> None:
        """The open pause's length for ``target`` s of speech wanted from now (mirrored by
        ``langenv.env_kernels.run``)."""
        if not math.isfinite(target):
            raise ActionError(
                f"SpeechTimeline.step: the pause target must be finite, got {target!r}"
            )
        u = self._phrase
        assert u is not None
        pos = self._pos
        length = self._graph._fill(u, pos + target)
        self._cur_slot = length if length > pos else pos
        self._mark = self._cur_slot

    def _advance(
        self,
        dt: float,
        a: float,
        adv: float,
        choice: Choice,
        t_x: Horizons,
        pause: PauseTarget,
    ) -> None:
        u = self._phrase
        assert u is not None
        dur, slot, kids = self._dur[u], self._cur_slot, self._children[u]
        # Resolve the first boundary's choice before changing anything (errors leave no trace).
        nxt: str | None = None
        nxt_len = 0.0
        if kids:
            rem, pos = adv, self._pos
            if not self._in_pause:
                rem -= dur - pos
                pos = dur
            if rem >= slot - pos:
                tau = (adv - rem + (slot - pos)) / a if a > 0.0 else 0.0
                nxt = self._resolve(u, kids, choice, t_x, tau)
                if nxt in self._pauses:
                    nxt_len = self._pause_length(nxt, pause, t_x, tau)

        t0 = self._t
        tau = 0.0  # time from the start of the step
        rem = adv  # content still to advance in this step
        while True:
            u = self._phrase
            assert u is not None
            dur, slot, kids = self._dur[u], self._cur_slot, self._children[u]
            if not self._in_pause:
                need = dur - self._pos
                if rem < need:
                    self._pos += rem
                    break
                tau += need / a if need > 0.0 else 0.0
                rem -= need
                self._pos = dur
                self._history.append(Utterance(u, self._t_start, t0 + tau))
                if not kids:
                    self._done = True
                    self._phrase = None
                    self._t_end = t0 + tau
                    self._content_done += dur
                    self._pos = 0.0
                    break
                self._in_pause = True
            need = slot - self._pos
            if rem < need:
                self._pos += rem
                break
            tau += need / a if need > 0.0 else 0.0
            rem -= need
            if u in self._pauses:
                self._history.append(Utterance(u, self._t_start, t0 + tau, slot))
                self._pause_lengths.append(slot)
            if nxt is None:  # a second boundary in the same step
                nxt = self._resolve(u, kids, choice if callable(choice) else None, t_x, tau, True)
                if nxt in self._pauses:
                    nxt_len = self._pause_length(nxt, pause, t_x, tau, True)
            self._content_done += slot
            self._enter(nxt, t0 + tau, nxt_len)
            if self._in_pause and rem >= nxt_len and self._gate_waits(nxt):
                # A gate that ends in the step it begins (its leg has begun) ends with the
                # step: the first words of its leg are the next step's choice, not the rule's.
                self._pos = nxt_len
                break
            nxt = None
        self._t = t0 + dt
        if self._phrase is not None:
            self._mark = self._cur_slot if self._in_pause else self._dur[self._phrase]

    def _enter(self, v: str, t_start: float, pause_length: float) -> None:
        """Make ``v`` the current vertex from ``t_start`` (a pause: ``pause_length`` long)."""
        self._phrase = v
        self._path.append(v)
        self._pos = 0.0
        self._t_start = t_start
        self._in_pause = v in self._pauses
        if self._in_pause:
            self._cur_slot = pause_length
            lo, hi = self._graph.slot_range(v)
            self._elastic = lo < hi
        else:
            self._cur_slot = self._slot[v]
            self._elastic = False

    def _gate_waits(self, v: str) -> bool:
        """Whether the gate ``v`` holds the rest of the step in which it is entered: a gate
        with a choice after it (its leg's first words are chosen at the next step)."""
        return self._graph.is_gate(v) and len(self._children[v]) > 1

    def _pause_length(
        self, v: str, pause: PauseTarget, t_x: Horizons, tau: float, fallback: bool = False
    ) -> float:
        """The length of the pause ``v`` being entered (see :meth:`step`)."""
        lo, hi = self._graph.slot_range(v)
        target = self._pause_target(v, pause, t_x)
        if target is not None:
            if isinstance(target, bool) or not isinstance(target, int | float):
                raise ActionError(
                    f"SpeechTimeline.step: pause target must be a number, got {target!r}"
                )
            if not math.isfinite(target):
                raise ActionError(
                    f"SpeechTimeline.step: the pause target must be finite, got {target!r}"
                )
            return self._graph.pause_length(v, target - tau)
        if fallback:
            return lo
        raise ActionError(
            f"SpeechTimeline.step: pause {v!r} is entered and its length is open "
            f"[{lo:g}, {hi:g}] s; pass `pause` or `t_x`"
        )

    def _resolve(
        self,
        u: str,
        kids: tuple[str, ...],
        choice: Choice,
        t_x: Horizons,
        tau: float,
        fallback: bool = False,
    ) -> str:
        if len(kids) == 1:
            return kids[0]  # nothing to decide: `choice` is not consulted
        if choice is not None:
            v = choice(kids) if callable(choice) else choice
            if v not in kids:
                raise ActionError(
                    f"SpeechTimeline.step: choice {v!r} is not a child of phrase {u!r}; "
                    f"candidates: {list(kids)}"
                )
            return v
        if t_x is not None:
            h = t_x if isinstance(t_x, int | float) else t_x[self._graph.choice_segment(u)]
            if not math.isfinite(h):
                raise ActionError(f"SpeechTimeline.step: t_x must be finite, got {t_x!r}")
            return self._graph.choose(u, h - tau)
        if fallback:
            return kids[0]
        raise ActionError(
            f"SpeechTimeline.step: phrase {u!r} ends and has several candidates {list(kids)}; "
            "pass `choice` or `t_x`"
        )

    # ------------------------------------------------------------------ compiled state
    def state_values(self) -> tuple[float, float, float, float, float, bool]:
        """``(speech_pos, speech_t, speech_a, mark, slot, in_pause)`` of
        :data:`TIMELINE_STATE` (the phrase's index is the caller's: it depends on its order)."""
        return self._pos, self._t, self._a, self._mark, self.slot_length, self._in_pause

    def take_state(self, pos: float, t: float, a: float, mark: float, slot: float) -> None:
        """Take the state back after compiled ticks inside the current vertex (an open pause's
        length and boundary, planned again at each tick, included)."""
        self._pos, self._t, self._a = pos, t, a
        if self._elastic:
            self._mark = mark
            self._cur_slot = slot

    @property
    def elastic(self) -> bool:
        """Whether the current vertex is a pause whose length is still open."""
        return self._elastic

    # ------------------------------------------------------------------ queries
    def boundary_due(self, horizon: float, a: float | None = None) -> bool:
        """Whether a choice of the next phrase will be needed within ``horizon`` seconds.

        True when the current phrase has children and its slot ends within ``horizon`` seconds
        at pace ``a`` (default: the pace of the last step). Final phrases never need a choice.
        """
        u = self._phrase
        if u is None or not self._children[u]:
            return False
        pace = self._a if a is None else a
        return self._cur_slot - self._pos <= pace * horizon

    def eta(self, t_x: float | Sequence[float], horizon: int | None = None) -> float:
        """Speech time to completion ``t_a`` at a = 1 (s), to the end of segment ``horizon``:
        see :meth:`PhraseGraph.eta`."""
        u = self._phrase
        if u is None:
            return 0.0
        return self._graph.eta(u, self._cur_slot - self._pos, t_x, horizon)

    def horizon_segment(self) -> int:
        """The segment whose end the speech's plan reaches now: the current vertex's children's
        (a gate's: the next leg's); the last once the speech is over."""
        u = self._phrase
        if u is None:
            return self._graph.segments - 1
        return self._graph.choice_segment(u)

    def said_at(self, t: float) -> str | None:
        """Id of the phrase or filler audible at time ``t`` (s); None in pauses, before 0, after
        the end."""
        u = self._phrase
        if u is not None and not self._in_pause and self._t_start <= t <= self._t:
            return u
        h = self._history
        i = bisect.bisect_right(h, t, key=lambda x: x.t_start) - 1
        if i >= 0 and t < h[i].t_end and h[i].length is None:
            return h[i].phrase
        return None

    def utterances(self) -> list[Utterance]:
        """The history plus the vertex playing now (its ``t_end`` is the current time): clips
        and pause vertices (with their chosen ``length``), in order."""
        out = list(self._history)
        u = self._phrase
        if u is not None and u in self._pauses:
            out.append(Utterance(u, self._t_start, self._t, self._pos))
        elif u is not None and not self._in_pause:
            out.append(Utterance(u, self._t_start, self._t))
        return out

    @property
    def graph(self) -> PhraseGraph:
        """The phrase graph spoken."""
        return self._graph

    @property
    def t(self) -> float:
        """Time since :meth:`reset` (s)."""
        return self._t

    @property
    def a(self) -> float:
        """Audio pace of the last step."""
        return self._a

    @property
    def phrase(self) -> str | None:
        """Current phrase (also during the pause after it); None once the speech is over."""
        return self._phrase

    @property
    def in_pause(self) -> bool:
        """True in the silence after the current phrase's clip."""
        return self._in_pause

    @property
    def done(self) -> bool:
        """True once the final phrase's clip has ended."""
        return self._done

    @property
    def position(self) -> float:
        """Base-pace seconds into the current phrase's slot (0 when done)."""
        return self._pos

    @property
    def remaining_in_phrase(self) -> float:
        """Base-pace seconds until the current slot ends: clip rest + pause (0 when done)."""
        u = self._phrase
        return 0.0 if u is None else self._cur_slot - self._pos

    @property
    def remaining_audio(self) -> float:
        """Base-pace seconds of the current clip still to play (0 in the pause and when done)."""
        u = self._phrase
        return 0.0 if u is None else max(0.0, self._dur[u] - self._pos)

    @property
    def fraction_said(self) -> float:
        """Share of the current phrase's clip already played, in [0, 1] (1 in pauses and done)."""
        u = self._phrase
        if u is None or self._in_pause:
            return 1.0
        return min(1.0, self._pos / self._dur[u])

    @property
    def candidates(self) -> tuple[str, ...]:
        """Children of the current phrase: the possible next phrases (empty when done/final)."""
        u = self._phrase
        return () if u is None else self._children[u]

    @property
    def history(self) -> list[Utterance]:
        """Finished utterances in order (do not modify; see :meth:`utterances`)."""
        return self._history

    @property
    def path(self) -> tuple[str, ...]:
        """Vertices started so far, in order (pauses included)."""
        return tuple(self._path)

    @property
    def pause_lengths(self) -> tuple[float, ...]:
        """Lengths of the pause vertices of :attr:`path`, in order (s at a = 1); a pause that
        lasts still counts with what has elapsed of it."""
        if self._phrase is not None and self._phrase in self._pauses:
            return (*self._pause_lengths, self._pos)
        return tuple(self._pause_lengths)

    @property
    def slot_length(self) -> float:
        """Base-pace length of the current vertex's slot (s; a pause's length as planned now;
        0 when done)."""
        return 0.0 if self._phrase is None else self._cur_slot

    @property
    def t_end(self) -> float | None:
        """Time the speech ended (s), None while it goes on."""
        return self._t_end

    @property
    def content_time(self) -> float:
        """Base-pace seconds of speech content played so far, pauses included (= ∫ a dt)."""
        return self._content_done + self._pos
