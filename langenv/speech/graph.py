"""Phrase graphs: what the robot may say, as a DAG of vertices, and the paper's choice rule.

A phrase graph (SPEC §4) is a directed acyclic graph whose edges say which vertex may follow which.
Speech starts at ``start`` and ends at a terminal vertex (no ``next``). A vertex is one of:

* a *phrase*: a text and/or a recorded clip;
* a *filler*: a short spoken clip ("okay", "so") that an edge may take or skip (the graph lists
  the filler and the vertex after it side by side in a ``next``); at most ``MAX_FILLER`` s long;
* a *pause*: silence whose length the controller chooses within ``[min, max]`` s when the pause
  is entered (:meth:`PhraseGraph.pause_length`). A pause neither starts nor ends the speech and
  never follows another pause.

Between a clip (phrase or filler) and the vertex after it there is ``pause`` seconds of silence at
audio pace 1 (a pause vertex lengthens that gap); there is none after the final phrase: the speech
is over when its last word ends. How the speech pace is voiced (the graph's ``voice``:
time-stretched, or a natural voice that waits at a clip's end) is :mod:`langenv.speech.voice`.

Time conventions (all at audio pace ``a = 1``, in seconds):

* ``duration[u]``: length of ``u``'s clip, measured from the audio itself (0 for a pause);
* ``slot(u)``: from the start of ``u`` to the start of the vertex after it, i.e.
  ``duration[u] + pause`` (just ``duration[u]`` for a terminal phrase); a pause's slot is the
  length chosen for it, within ``slot_range(u) = (min, max)``;
* ``t_min(u)``, ``t_max(u)``: shortest/longest speech from the start of ``u`` to the end of the
  speech, computed in reverse topological order:
  ``t_min(u) = min slot(u) + min over children v of t_min(v)`` (``duration[u]`` for a terminal).

The next vertex is chosen when the current one's slot ends, with the paper's rule
``argmin over children v of |t_x - (t_min(v) + t_max(v)) / 2|`` (ties: the child listed first in
``next``); at that instant the remaining speech is exactly ``t_min(v)..t_max(v)``, which is what
the rule compares with the motion's time to completion ``t_x``. The rule never looks at the paces.
"""

from __future__ import annotations

import copy
import itertools
import math
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path
from types import MappingProxyType
from typing import Any

import numpy as np

from langenv.errors import AudioError, ConfigError, PhraseGraphError
from langenv.speech.audio import ClipLibrary
from langenv.speech.choice import nearest
from langenv.speech.graph_checks import GraphParts, graph_problems, topological_order, vertex_table
from langenv.speech.graph_file import read_graph_file
from langenv.speech.legs import add_gates, segment_of, unrolled_legs
from langenv.speech.phrase import DEFAULT_PAUSE, Phrase
from langenv.speech.repeat import (
    SEP,
    WAIT_MAX,
    Repeat,
    expand,
    is_gap,
    reopen_vertex,
)
from langenv.speech.voice import VOICES, Voice

__all__ = [
    "GRAPHS_DIR",
    "SHIPPED_GRAPHS",
    "PhraseGraph",
    "default_graph_path",
    "graph_path",
]


GRAPHS_DIR = Path(__file__).resolve().parents[1] / "assets" / "graphs"
"""Directory of the phrase graphs shipped with the package."""

SHIPPED_GRAPHS: Mapping[str, Path] = MappingProxyType(
    {
        # The product's graph for the default exercise: the study's wordings, shorter late
        # wordings, pauses and fillers (written from default.txt by `langctrl speech
        # author`). LC speaks it unless told otherwise.
        "default": GRAPHS_DIR / "default.yaml",
        "lc": GRAPHS_DIR / "default.yaml",
        # The study's LC graph, unchanged: what eval.fidelity compares with the recordings.
        "study": GRAPHS_DIR / "study.yaml",
        "lc-noap": GRAPHS_DIR / "lc_noap.yaml",
        # AC says the same single wording as LC-noAP, at a = 1 (the study's AC and LC-noAP
        # speech both lasted about 13.4 s): one prerecorded utterance with its pauses.
        "ac": GRAPHS_DIR / "lc_noap.yaml",
    }
)
"""The shipped phrase graphs of the default exercise, by name (the one place names resolve):
``default`` (also ``lc``, LC's graph), ``study`` (the study's LC graph), ``lc-noap`` and ``ac``."""


def default_graph_path(name: str) -> Path:
    """Path of a shipped phrase graph.

    Args:
        name: A key of :data:`SHIPPED_GRAPHS` (``_`` for ``-`` also accepted).

    Raises:
        ConfigError: naming ``name`` when no such graph ships with the package.
    """
    path = SHIPPED_GRAPHS.get(name.replace("_", "-"))
    if path is None:
        known = sorted(SHIPPED_GRAPHS)
        raise ConfigError(f"no shipped phrase graph named {name!r}; known: {known}")
    return path


def graph_path(spec: str | Path) -> Path:
    """A phrase graph given as a shipped graph's name (:data:`SHIPPED_GRAPHS`; ``_`` for ``-``
    also accepted) or a YAML path."""
    name = str(spec).replace("_", "-")
    return SHIPPED_GRAPHS[name] if name in SHIPPED_GRAPHS else Path(spec)


class PhraseGraph:
    """A validated phrase DAG with clip durations, ``t_min``/``t_max`` and the choice rule.

    Build one with :meth:`load` from a YAML file (SPEC §4), or directly from vertices and
    durations (tests, programmatic graphs).

    Args:
        phrases: The vertices (a mapping id -> :class:`Phrase`, or an iterable of them).
        start: Id of the first phrase.
        duration: Clip length at a = 1 of every phrase and filler (s, > 0; pauses need none).
        pause: Silence after each clip at a = 1 (s, in [0, 10]).
        voice: How the speech pace is voiced: ``"stretch"`` (the paper: the voice is
            time-stretched by ``a``) or ``"natural"`` (clips said at ``max(a, 0.9)``, then a wait
            until the timeline reaches their end); see :mod:`langenv.speech.voice`. It changes
            the sound only, never the timeline.
        path: File the graph came from, named in error messages (None: built in memory).
        repeats: Groups of phrases that may be said again (:mod:`langenv.speech.repeat`).
        final_wait: Whether the last phrase waits for the motion (:mod:`langenv.speech.repeat`);
            off by default, as in the paper and in a graph file without the key; a script turns
            it on unless it says ``@final-wait off``.
        legs: The names of the exercise's legs the script speaks about, in order
            (:mod:`langenv.speech.legs`); empty (the default): an unmarked graph, aligned with
            the whole motion as in the paper.
        leg_of: The leg of each of the graph's own vertices (required for all of them when
            ``legs`` is given).
        intents: The intent (:data:`~langenv.speech.intents.INTENTS`) of those of the graph's
            own phrases that carry one (:meth:`intent`); fillers and pauses carry none.

    The vertices given are the graph's *own*; :attr:`phrases` holds them unrolled (repeats and
    the wait before the last phrase, :mod:`langenv.speech.repeat`), which is what the timeline
    says; :attr:`source_phrases` the ones given.

    Raises:
        PhraseGraphError: listing every problem, one per line, each naming the file and the
            vertex: unknown ``start`` or ``next`` id, duplicate ``next`` entries, a cycle (with the
            vertices on it), a vertex that cannot reach a terminal, a pause that starts or ends
            the speech or follows a pause, a missing or bad duration,
            a filler longer than ``MAX_FILLER``, a bad pause, an id with ``#``, a repeat that is
            not possible (``repeat_problems``).
    """

    def __init__(
        self,
        phrases: Mapping[str, Phrase] | Iterable[Phrase],
        start: str,
        duration: Mapping[str, float],
        *,
        pause: float = DEFAULT_PAUSE,
        voice: str = "stretch",
        path: str | Path | None = None,
        repeats: Mapping[str, Repeat] | Iterable[Repeat] = (),
        final_wait: bool = False,
        legs: Iterable[str] = (),
        leg_of: Mapping[str, str] | None = None,
        intents: Mapping[str, str] | None = None,
    ) -> None:
        self.path: Path | None = None if path is None else Path(path)
        label = str(self.path) if self.path is not None else "<phrase graph>"
        table, found = vertex_table(label, phrases)
        reps = dict(repeats) if isinstance(repeats, Mapping) else {r.name: r for r in repeats}
        legs = tuple(legs)
        own_legs, own_intents = dict(leg_of or {}), dict(intents or {})
        parts = GraphParts(pause, voice, reps, final_wait, legs, own_legs, own_intents)
        problems = graph_problems(label, table, start, duration, parts, found)
        if problems:
            raise PhraseGraphError("\n".join(problems))

        self.start: str = start
        self.pause: float = float(pause)
        self.voice: Voice = voice  # type: ignore[assignment]
        """How the speech pace is voiced (:data:`langenv.speech.voice.VOICES`)."""
        self.source_phrases: Mapping[str, Phrase] = MappingProxyType(dict(table))
        """The graph's own vertices, as given (before unrolling)."""
        self.repeats: Mapping[str, Repeat] = MappingProxyType(reps)
        """The graph's repeats by name."""
        self.final_wait: bool = final_wait
        """Whether the last phrase waits for the motion."""
        self.legs: tuple[str, ...] = legs
        """The exercise's legs the script speaks about, in order (empty: an unmarked graph)."""
        self.leg_of: Mapping[str, str] = MappingProxyType(own_legs)
        """The leg of each of the graph's own vertices (empty: an unmarked graph)."""
        self.intent_of: Mapping[str, str] = MappingProxyType(own_intents)
        """The intent of each of the graph's own phrases that carries one (:meth:`intent`)."""
        own = {pid: float(duration[pid]) for pid, ph in table.items() if not ph.is_pause}
        table, clip_len, opened = expand(table, own, reps, final_wait, Phrase)
        gates = self._segment(table, reps, own_legs)
        if gates:
            opened = opened | gates[1]
        self._gates: frozenset[str] = frozenset(gates[0]) if gates else frozenset()
        self.phrases: Mapping[str, Phrase] = MappingProxyType(table)
        """Every vertex the speech may say, repeats, waits and gates unrolled, by id."""
        self.duration: Mapping[str, float] = MappingProxyType(
            {pid: 0.0 if ph.is_pause else clip_len[pid] for pid, ph in table.items()}
        )
        self.opened: frozenset[str] = opened
        """The pauses open above their bounds: the silences before the last phrase and the
        gates between legs (:mod:`langenv.speech.legs`)."""
        self._build_tables(table)
        self.reopen: str | None = reopen_vertex(self)
        """Where the speech goes on when the motion goes back after its end (None: it does
        not; :func:`~langenv.speech.repeat.reopen_vertex`)."""

    def _segment(
        self, table: dict[str, Phrase], reps: Mapping[str, Repeat], own: Mapping[str, str]
    ) -> tuple[set[str], set[str]] | None:
        """Each unrolled vertex's segment and leg, and the gates between segments (in place;
        :mod:`langenv.speech.legs`); None for an unmarked graph (one segment)."""
        if not self.legs:
            self._seg = dict.fromkeys(table, 0)
            self._leg: dict[str, str | None] = dict.fromkeys(table)
            self.segment_names: tuple[str, ...] = ()
            return None
        rep_legs = {r.name: own[r.phrases[0]] for r in reps.values()}
        leg = unrolled_legs(table, own, rep_legs)
        seg = segment_of(table, self.legs, leg, topological_order(table))
        names = tuple(n for n in self.legs if any(leg[u] == n and not table[u].is_pause
                                                  for u in table))  # fmt: skip
        self.segment_names = names
        """The legs with words, in order: the segments (empty for an unmarked graph)."""
        gates = add_gates(table, seg, names, Phrase)
        self._seg = seg
        self._leg = {u: leg[u] if u in leg and not table[u].is_pause else names[seg[u]]
                     for u in table}  # fmt: skip
        return gates

    def _build_tables(self, table: Mapping[str, Phrase]) -> None:
        """The order, slots, ``t_min``/``t_max`` and the choice rule's mids of the vertices."""
        self.order: tuple[str, ...] = topological_order(table)
        """Vertex ids in topological order (every vertex before the vertices that follow it)."""
        self._children = {pid: ph.next for pid, ph in table.items()}
        self._plan: dict[str, tuple[float, float]] = {}
        for pid, ph in table.items():
            if ph.bounds is not None:
                self._plan[pid] = ph.bounds
            else:
                d = self.duration[pid] + (self.pause if ph.next else 0.0)
                self._plan[pid] = (d, d)
        # what a pause may last (an opened one: up to WAIT_MAX), and what plans count with
        self._lo = {pid: lo for pid, (lo, _) in self._plan.items()}
        self._hi = {
            pid: WAIT_MAX if pid in self.opened else hi for pid, (_, hi) in self._plan.items()
        }
        # a pause's nominal slot (its planned middle length) is what plans beyond the next pause
        # assume
        self._slot = {pid: 0.5 * (lo + hi) for pid, (lo, hi) in self._plan.items()}
        # plans stop at a segment's end: a gate's children begin the next one
        self._plan_kids = {
            u: () if u in self._gates else kids for u, kids in self._children.items()
        }
        self._t_min, self._t_max = self._ranges(self._plan_kids)
        self._whole = (
            (self._t_min, self._t_max) if not self._gates else self._ranges(self._children)
        )
        t_min, t_max = self._t_min, self._t_max
        self._mid = {pid: 0.5 * (t_min[pid] + t_max[pid]) for pid in table}
        self.max_children: int = max(len(k) for k in self._children.values())
        """Largest number of children of any vertex (0 for a single-phrase graph)."""
        self.pauses: frozenset[str] = frozenset(p for p, ph in table.items() if ph.is_pause)
        """Ids of the pause vertices."""
        self.fillers: frozenset[str] = frozenset(
            p for p, ph in table.items() if ph.kind == "filler"
        )
        """Ids of the filler vertices."""

    def _ranges(
        self, children: Mapping[str, tuple[str, ...]]
    ) -> tuple[dict[str, float], dict[str, float]]:
        """``t_min``/``t_max`` of every vertex to the end of the walk ``children`` allows."""
        t_min: dict[str, float] = {}
        t_max: dict[str, float] = {}
        for pid in reversed(self.order):
            # a plan says a repeat once: a gap (another saying) is a choice, not part of the range
            kids = tuple(v for v in children[pid] if not is_gap(v)) or children[pid]
            lo, hi = self._plan[pid]
            if kids:
                t_min[pid] = lo + min(t_min[v] for v in kids)
                t_max[pid] = hi + max(t_max[v] for v in kids)
            else:
                t_min[pid] = lo
                t_max[pid] = hi
        return t_min, t_max

    # ------------------------------------------------------------------ loading
    @classmethod
    def load(cls, path: str | Path, clips: ClipLibrary | None = None) -> PhraseGraph:
        """Read, validate and measure a phrase graph file (SPEC §4).

        Phrase ``audio`` paths are relative to the file's directory. Durations come from the
        audio itself: each phrase's recorded clip, or its text spoken by ``clips``' TTS.

        Args:
            path: The YAML file.
            clips: Where phrase audio comes from; None: a default :class:`ClipLibrary`.

        Returns:
            The validated graph.

        Raises:
            PhraseGraphError: listing every problem found, one per line, each naming the file and
                (where it applies) the phrase: unreadable file, bad YAML, unknown keys, bad
                ``pause``, unknown ``start``/``next`` ids, a phrase or filler with neither
                ``text`` nor ``audio``, pause bounds that are not ``[min, max]`` with
                ``0 <= min <= max <= 10``, a cycle, a vertex that cannot reach a terminal or
                that ``start`` never reaches, a pause that starts or ends the speech or follows
                another, a filler clip longer than ``MAX_FILLER``, a missing or unreadable
                audio file.
        """
        found = read_graph_file(path)
        path, phrases, parts = found.path, found.phrases, found.parts
        problems: list[str] = []
        if clips is None:
            clips = ClipLibrary()
        durations: dict[str, float] = {}
        for pid, ph in phrases.items():
            if ph.is_pause:
                continue
            if ph.audio is not None and not ph.audio.is_file():
                problems.append(f"{path}: {ph.kind} {pid!r}: audio file {ph.audio} does not exist")
                continue
            try:
                durations[pid] = clips.duration(ph)
            except AudioError as exc:  # its message names the audio file and the phrase
                problems.append(f"{path}: {exc}")
        if problems:
            raise PhraseGraphError("\n".join(problems))
        return cls(
            phrases,
            found.start,
            durations,
            pause=float(parts.pause),  # type: ignore[arg-type]
            voice=str(parts.voice),
            path=path,
            repeats=parts.repeats,
            final_wait=bool(parts.final_wait),
            legs=parts.legs,
            leg_of=parts.leg_of,
            intents=parts.intents,
        )

    def with_voice(self, voice: str) -> PhraseGraph:
        """The same graph voiced as ``voice`` (:data:`langenv.speech.voice.VOICES`): a replay
        voiced as its session was (:attr:`eval.episode.EpisodeLog.voice`), whatever the YAML
        says today.

        Raises:
            PhraseGraphError: naming the graph, for an unknown voice.
        """
        if voice == self.voice:
            return self
        if voice not in VOICES:
            raise PhraseGraphError(
                f"{self._label}: voice must be one of {list(VOICES)}, got {voice!r}"
            )
        graph = copy.copy(self)  # the voice changes no vertex, slot or table
        graph.voice = voice
        return graph

    # ------------------------------------------------------------------ structure
    def children(self, u: str) -> tuple[str, ...]:
        """Ids of the phrases that may follow ``u`` (empty for a terminal phrase)."""
        try:
            return self._children[u]
        except KeyError:
            raise PhraseGraphError(f"{self._label}: no phrase {u!r}") from None

    def is_terminal(self, u: str) -> bool:
        """True when ``u`` ends the speech."""
        return not self.children(u)

    def slot(self, u: str) -> float:
        """Time from the start of ``u`` to the start of its successor at a = 1 (s).

        ``duration[u] + pause``; ``duration[u]`` alone for a terminal phrase; for a pause, the
        middle of its bounds (its length is chosen when it is entered: :meth:`pause_length`).
        """
        try:
            return self._slot[u]
        except KeyError:
            raise PhraseGraphError(f"{self._label}: no phrase {u!r}") from None

    def slot_range(self, u: str) -> tuple[float, float]:
        """Shortest and longest slot of ``u`` at a = 1 (s): a pause's bounds (an opened pause,
        :attr:`opened`: up to :data:`~langenv.speech.repeat.WAIT_MAX`), else ``slot(u)`` twice."""
        try:
            return self._lo[u], self._hi[u]
        except KeyError:
            raise PhraseGraphError(f"{self._label}: no phrase {u!r}") from None

    def plan_range(self, u: str) -> tuple[float, float]:
        """The slot range ``t_min``/``t_max`` and the choice rule count with (s at a = 1): the
        pause's bounds as written (0 to ``WAIT_PLAN`` for a wait before the last phrase), else
        ``slot(u)`` twice."""
        try:
            return self._plan[u]
        except KeyError:
            raise PhraseGraphError(f"{self._label}: no phrase {u!r}") from None

    def origin(self, u: str) -> str:
        """The graph's own vertex an unrolled vertex says (``keep_going#3`` -> ``keep_going``);
        a gap or a wait gives its own id."""
        self.children(u)  # validates u
        base = u.split(SEP, 1)[0]
        return base if base in self.source_phrases and u not in self.pauses else u

    def kind(self, u: str) -> str:
        """``"phrase"``, ``"filler"`` or ``"pause"``."""
        try:
            return self.phrases[u].kind
        except KeyError:
            raise PhraseGraphError(f"{self._label}: no phrase {u!r}") from None

    def leg(self, u: str) -> str | None:
        """The leg of the exercise vertex ``u`` speaks about (a pause or gate: the leg whose
        silence it is); None for an unmarked graph."""
        try:
            return self._leg[u]
        except KeyError:
            raise PhraseGraphError(f"{self._label}: no phrase {u!r}") from None

    def intent(self, u: str) -> str | None:
        """The intent (:data:`~langenv.speech.intents.INTENTS`) of the wording ``u`` says: its
        own vertex's (an unrolled vertex, ``keep_going#3``, inherits it); None for a wording
        without one, a filler or a pause.

        Raises:
            PhraseGraphError: naming the graph, for an id it lacks.
        """
        if self.kind(u) == "pause":
            return None
        return self.intent_of.get(self.origin(u))

    def segment(self, u: str) -> int:
        """The segment of ``u`` (:mod:`langenv.speech.legs`; 0 for an unmarked graph)."""
        try:
            return self._seg[u]
        except KeyError:
            raise PhraseGraphError(f"{self._label}: no phrase {u!r}") from None

    def is_gate(self, u: str) -> bool:
        """Whether ``u``'s children begin the next segment (the silence before a leg's words)."""
        return u in self._gates

    @property
    def segments(self) -> int:
        """Number of segments (1 for an unmarked graph)."""
        return max(1, len(self.segment_names))

    def choice_segment(self, u: str) -> int:
        """The segment of ``u``'s children (whose mids a choice at ``u``'s end compares with
        the motion's time to that segment's end); ``u``'s own for a terminal."""
        kids = self.children(u)
        return self._seg[kids[0]] if kids else self._seg[u]

    def speech_range(self, u: str | None = None) -> tuple[float, float]:
        """Shortest and longest speech from the start of ``u`` (default: start) to the end of
        the whole speech, at a = 1 (s); ``(t_min(u), t_max(u))`` for an unmarked graph."""
        v = self.start if u is None else u
        self.children(v)  # validates v
        return self._whole[0][v], self._whole[1][v]

    def t_min(self, u: str) -> float:
        """Shortest speech from the start of ``u`` to the end of its segment's lines (the end of
        the speech for an unmarked graph), pauses included, at a = 1 (s)."""
        try:
            return self._t_min[u]
        except KeyError:
            raise PhraseGraphError(f"{self._label}: no phrase {u!r}") from None

    def t_max(self, u: str) -> float:
        """Longest speech from the start of ``u`` to the end of its segment's lines, pauses
        included, at a = 1 (s)."""
        try:
            return self._t_max[u]
        except KeyError:
            raise PhraseGraphError(f"{self._label}: no phrase {u!r}") from None

    # ------------------------------------------------------------------ the choice rule
    def choose(self, u: str, t_x: float) -> str:
        """The paper's rule: the child ``v`` of ``u`` minimising ``|t_x - (t_min+t_max)(v)/2|``.

        Ties go to the child listed first in ``u``'s ``next``.

        Args:
            u: The phrase that is ending.
            t_x: Motion time to completion at the moment of the choice (s, base pace).

        Raises:
            PhraseGraphError: if ``u`` is unknown or terminal.
        """
        kids = self.children(u)
        if not kids:
            raise PhraseGraphError(f"{self._label}: phrase {u!r} is terminal: nothing to choose")
        return nearest(kids, self._mid, t_x)

    def nearest(self, kids: Sequence[str], x: float) -> str:
        """The choice rule among ``kids`` (phrases of this graph, non-empty): the first whose
        middle length ``(t_min + t_max)/2`` is nearest ``x`` (s) (:meth:`choose` with ``x``
        for ``t_x``; :func:`langenv.speech.choice.nearest`)."""
        return nearest(kids, self._mid, x)

    def eta(
        self,
        u: str,
        remaining_in_u: float,
        t_x: float | Sequence[float],
        horizon: int | None = None,
    ) -> float:
        """Speech time to completion ``t_a`` at a = 1 (SPEC §1), to the end of segment
        ``horizon`` (:mod:`langenv.speech.legs`).

        The rest of the current vertex's slot plus the slots of the vertices that repeated use of
        :meth:`choose` would take, each choice evaluated with the motion's time to the end of
        the children's segment left at that moment (that time minus the base-pace speech until
        the choice), each pause at the length :meth:`pause_length` would give it then; the walk
        stops where the speech would enter a segment after ``horizon``.

        Args:
            u: The current vertex.
            remaining_in_u: Base-pace time until ``u``'s slot ends (its pause included) (s).
            t_x: The motion's time to the end of each segment now (s; a number for an unmarked
                graph: its time to completion).
            horizon: The last segment counted; None: the last.

        Returns:
            Seconds of speech left at a = 1 (without a trailing pause after the final phrase).
        """
        hz = self._horizons(t_x)
        last = len(hz) - 1 if horizon is None else horizon
        kids = self.children(u)
        total = remaining_in_u
        cur, left = -1, 0.0
        slot, mid, children, lo, hi = self._slot, self._mid, self._children, self._lo, self._hi
        seg = self._seg
        while kids:
            j = seg[kids[0]]
            if j > last:
                break
            if j != cur:  # entering a segment: the motion's time to its end, less the speech so far
                cur, left = j, hz[j] - total
            v = nearest(kids, mid, left)
            length = slot[v] if lo[v] == hi[v] else self._fill(v, left)
            total += length
            left -= length
            kids = children[v]
        return total

    def _horizons(self, t_x: float | Sequence[float]) -> Sequence[float]:
        """The motion's times to each segment's end (a number: the one segment's)."""
        if isinstance(t_x, int | float):
            if self.segments != 1:
                raise PhraseGraphError(
                    f"{self._label}: the graph speaks about {self.segments} legs: pass the "
                    "motion's time to the end of each (langenv.speech.legs.LegPlan.horizons)"
                )
            return (t_x,)
        if len(t_x) != self.segments:
            raise PhraseGraphError(
                f"{self._label}: {len(t_x)} horizons for {self.segments} segments"
            )
        return t_x

    def pause_length(self, u: str, target: float) -> float:
        """Length of silence (s at a = 1) for the pause ``u`` entered with ``target`` seconds of
        speech wanted from its start (the analytic rule passes the motion's ``t_x``).

        The aligner's logic applied to the pause: the length that makes the speech from here end
        at ``target`` — ``target`` minus the speech after the pause as the choice rule would
        take it (its choices made as if this pause took its middle length, later pauses at
        theirs) — clipped to the pause's bounds. Like :meth:`choose`, it never looks at the
        paces.

        Raises:
            PhraseGraphError: if ``u`` is not a pause of this graph.
        """
        ph = self.phrases.get(u)
        if ph is None or not ph.is_pause:
            raise PhraseGraphError(f"{self._label}: {u!r} is not a pause of this graph")
        if not math.isfinite(target):
            raise PhraseGraphError(
                f"{self._label}: pause {u!r}: target must be finite, got {target!r}"
            )
        return self._fill(u, float(target))

    def _fill(self, v: str, left: float) -> float:
        """:meth:`pause_length` without checks (mirrored by
        :func:`langenv.speech.graph_kernels.fill`)."""
        slot, mid, children = self._slot, self._mid, self._plan_kids
        y = left - slot[v]
        rest = 0.0
        kids = children[v]
        while kids:
            w = nearest(kids, mid, y)
            rest += slot[w]
            y -= slot[w]
            kids = children[w]
        length = left - rest
        lo, hi = self._lo[v], self._hi[v]
        return lo if length < lo else (hi if length > hi else length)

    def packed(self, order: tuple[str, ...]) -> tuple[np.ndarray, ...]:
        """The graph as arrays for :mod:`langenv.speech.graph_kernels`: ``mid`` (n), ``slot``
        (n, 3: the nominal slot, its minimum and maximum, which differ for a pause only), by
        index in ``order``, the children's offsets ``kid_ptr`` (n + 1) and indexes ``kids``, in
        the graph's order."""
        index = {u: i for i, u in enumerate(order)}
        mid = np.array([self._mid[u] for u in order])
        slot = np.array([(self.slot(u), *self.slot_range(u)) for u in order]).reshape(-1, 3)
        kids = [index[v] for u in order for v in self.children(u)]
        counts = [len(self.children(u)) for u in order]
        kid_ptr = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)
        return mid, slot, kid_ptr, np.array(kids, dtype=np.int64)

    def shortest_path(self, u: str | None = None) -> tuple[str, ...]:
        """A path from ``u`` (default: start) to a terminal whose speech lasts ``t_min(u)``."""
        return self._extreme_path(self.start if u is None else u, 0, min)

    def longest_path(self, u: str | None = None) -> tuple[str, ...]:
        """A path from ``u`` (default: start) to a terminal whose speech lasts ``t_max(u)``."""
        return self._extreme_path(self.start if u is None else u, 1, max)

    def path_length(self, path: Iterable[str]) -> float:
        """Speech length of a path at a = 1 (s): slots, without a trailing pause; each pause at
        the middle of its bounds (:meth:`path_range` gives the extremes).

        Raises:
            PhraseGraphError: if ``path`` is empty, names an unknown vertex or skips an edge.
        """
        lo, hi = self.path_range(path)
        return 0.5 * (lo + hi)

    def path_range(self, path: Iterable[str]) -> tuple[float, float]:
        """Shortest and longest speech along a path at a = 1 (s): its pauses at their planned
        bounds (:meth:`plan_range`: a wait before the last phrase as 0).

        Raises:
            PhraseGraphError: if ``path`` is empty, names an unknown vertex or skips an edge.
        """
        ids = list(path)
        if not ids:
            raise PhraseGraphError(f"{self._label}: empty path")
        for u in ids:
            self.children(u)  # validates u
        for u, v in itertools.pairwise(ids):
            if v not in self.children(u):
                raise PhraseGraphError(f"{self._label}: phrase {v!r} does not follow {u!r}")
        last = ids[-1]
        end_lo, end_hi = (
            self._plan[last] if last in self.pauses else (self.duration[last], self.duration[last])
        )
        lo = sum(self._plan[u][0] for u in ids[:-1]) + end_lo
        hi = sum(self._plan[u][1] for u in ids[:-1]) + end_hi
        return lo, hi

    def count_paths(self, u: str | None = None, *, once: bool = False) -> int:
        """Number of distinct paths from ``u`` (default: start) to a terminal; ``once``: with
        each repeat said once (a repeat's gaps left out, as a plan counts)."""
        counts: dict[str, int] = {}
        for pid in reversed(self.order):
            kids = self._path_children(pid, once)
            counts[pid] = sum(counts[v] for v in kids) if kids else 1
        return counts[self.start if u is None else u]

    def paths(
        self, u: str | None = None, *, limit: int = 100_000, once: bool = False
    ) -> list[tuple[str, ...]]:
        """Every path from ``u`` (default: start) to a terminal, depth first, children in order;
        ``once``: the paths that say each repeat once (no gap: the paths a plan counts).

        Raises:
            ConfigError: if there are more than ``limit`` paths (use :meth:`count_paths`).
        """
        root = self.start if u is None else u
        n = self.count_paths(root, once=once)
        if n > limit:
            raise ConfigError(f"paths: {n} paths from {root!r} exceed limit={limit}")
        out: list[tuple[str, ...]] = []
        stack: list[tuple[str, ...]] = [(root,)]
        while stack:
            p = stack.pop()
            kids = self._path_children(p[-1], once)
            if not kids:
                out.append(p)
            for v in reversed(kids):
                stack.append((*p, v))
        return out

    def _path_children(self, u: str, once: bool) -> tuple[str, ...]:
        kids = self._children[u]
        if not once:
            return kids
        return tuple(v for v in kids if not is_gap(v)) or kids

    def reachable(self) -> frozenset[str]:
        """Phrases that some speech from ``start`` can say."""
        seen = {self.start}
        stack = [self.start]
        while stack:
            for v in self._children[stack.pop()]:
                if v not in seen:
                    seen.add(v)
                    stack.append(v)
        return frozenset(seen)

    def __len__(self) -> int:
        return len(self.phrases)

    def __repr__(self) -> str:
        return (
            f"PhraseGraph({self._label!r}, {len(self.phrases)} phrases, start={self.start!r}, "
            f"pause={self.pause}, speech {self.speech_range()[0]:.2f}-"
            f"{self.speech_range()[1]:.2f} s)"
        )

    # ------------------------------------------------------------------ internals
    @property
    def _label(self) -> str:
        return str(self.path) if self.path is not None else "<phrase graph>"

    def _extreme_path(self, u: str, which: int, pick: Any) -> tuple[str, ...]:
        table = self._whole[which]
        self.children(u)  # validates u
        path = [u]
        while kids := self._path_children(path[-1], True):  # as t_min/t_max: a repeat once
            best = pick(table[v] for v in kids)
            path.append(next(v for v in kids if table[v] == best))
        return tuple(path)
