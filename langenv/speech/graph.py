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

import itertools
import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from types import MappingProxyType
from typing import Any

import numpy as np

from langenv.errors import AudioError, ConfigError, PhraseGraphError
from langenv.speech.audio import ClipLibrary
from langenv.speech.intents import intent_problem
from langenv.speech.legs import add_gates, leg_problems, segment_of, unrolled_legs
from langenv.speech.repeat import (
    SEP,
    WAIT_MAX,
    Repeat,
    expand,
    is_gap,
    parse_repeats,
    repeat_problems,
)
from langenv.speech.voice import VOICES, Voice

__all__ = [
    "DEFAULT_PAUSE",
    "GRAPHS_DIR",
    "KINDS",
    "MAX_FILLER",
    "SHIPPED_GRAPHS",
    "Phrase",
    "PhraseGraph",
    "default_graph_path",
    "graph_path",
]

DEFAULT_PAUSE = 1.0
"""Silence after each clip at a = 1 (s) when a graph file gives no ``pause`` (SPEC §2)."""

MAX_FILLER = 1.5
"""Longest clip a filler may have at a = 1 (s): fillers are short words."""

KINDS = ("phrase", "filler", "pause")
"""The kinds of phrase-graph vertices."""

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

_TOP_KEYS = frozenset({"start", "pause", "phrases", "voice", "repeats", "final_wait", "legs"})
_PHRASE_KEYS = frozenset({"text", "audio", "next", "filler", "pause", "leg", "intent"})
_MAX_PAUSE = 10.0


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


@dataclass(frozen=True)
class Phrase:
    """One vertex of a phrase graph: a phrase, a filler or a pause.

    Attributes:
        id: Unique name of the vertex in its graph.
        text: What it says (used for TTS when ``audio`` is None, and for subtitles); None for a
            pause.
        audio: Recorded clip (absolute path, or relative to the working directory); None: TTS
            (and always for a pause).
        next: Ids of the vertices that may follow, in preference order for ties; empty: terminal.
        kind: ``"phrase"``, ``"filler"`` (a short clip an edge may take or skip) or ``"pause"``.
        bounds: A pause's ``(min, max)`` length of silence at a = 1 (s, ``0 <= min <= max <= 10``);
            None for a phrase or filler.
    """

    id: str
    text: str | None
    audio: Path | None
    next: tuple[str, ...] = ()
    kind: str = "phrase"
    bounds: tuple[float, float] | None = None

    def __post_init__(self) -> None:
        if not isinstance(self.id, str) or not self.id:
            raise PhraseGraphError(f"Phrase.id must be a non-empty str, got {self.id!r}")
        if self.kind not in KINDS:
            raise PhraseGraphError(
                f"vertex {self.id!r}: kind must be one of {KINDS}, got {self.kind!r}"
            )
        if self.text is not None and (not isinstance(self.text, str) or not self.text.strip()):
            raise PhraseGraphError(f"{self.kind} {self.id!r}: text must be a non-empty str or None")
        if self.audio is not None and not isinstance(self.audio, Path):
            object.__setattr__(self, "audio", Path(self.audio))
        if self.kind == "pause":
            if self.text is not None or self.audio is not None:
                raise PhraseGraphError(f"pause {self.id!r}: a pause has no 'text' or 'audio'")
            problem = _bounds_problem(self.bounds)
            if problem:
                raise PhraseGraphError(f"pause {self.id!r}: {problem}")
            lo, hi = self.bounds  # type: ignore[misc]
            object.__setattr__(self, "bounds", (float(lo), float(hi)))
        else:
            if self.bounds is not None:
                raise PhraseGraphError(f"{self.kind} {self.id!r}: only a pause has bounds")
            if self.text is None and self.audio is None:
                what = "no audio: give 'text' (spoken by TTS) or 'audio'"
                reason = what if self.kind == "filler" else "has neither 'text' nor 'audio'"
                raise PhraseGraphError(f"{self.kind} {self.id!r}: {reason}")
        nxt = (self.next,) if isinstance(self.next, str) else tuple(self.next)
        if not all(isinstance(v, str) for v in nxt):
            raise PhraseGraphError(f"{self.kind} {self.id!r}: next must be a list of vertex ids")
        object.__setattr__(self, "next", nxt)

    @property
    def terminal(self) -> bool:
        """True when nothing follows this vertex."""
        return not self.next

    @property
    def is_pause(self) -> bool:
        """True for a pause (silence of a chosen length)."""
        return self.kind == "pause"


def _bounds_problem(bounds: object) -> str:
    """Why ``bounds`` are not a pause's ``[min, max]`` seconds ('' when they are)."""
    if not isinstance(bounds, list | tuple) or len(bounds) != 2:
        return f"'pause' must be [min, max] seconds of silence, got {bounds!r}"
    lo, hi = bounds
    if not (_is_number(lo) and _is_number(hi)):
        return f"pause bounds must be numbers of seconds, got {list(bounds)!r}"
    if lo < 0.0 or hi < 0.0:
        return f"pause bounds must not be negative, got [{lo}, {hi}]"
    if lo > hi:
        return f"pause bounds are reversed: min {lo} > max {hi}"
    if hi > _MAX_PAUSE:
        return f"pause max must be at most {_MAX_PAUSE} s, got {hi}"
    return ""


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
        items = list(phrases.values()) if isinstance(phrases, Mapping) else list(phrases)
        table: dict[str, Phrase] = {}
        problems: list[str] = []
        for ph in items:
            if not isinstance(ph, Phrase):
                raise PhraseGraphError(f"{label}: phrases must be Phrase objects, got {ph!r}")
            if ph.id in table:
                problems.append(f"{label}: {ph.kind} {ph.id!r}: defined twice")
            table[ph.id] = ph
        if isinstance(phrases, Mapping):
            for key, ph in phrases.items():
                if key != ph.id:
                    problems.append(
                        f"{label}: phrase {key!r}: stored under a different id {ph.id!r}"
                    )
        if not _is_number(pause) or not 0.0 <= float(pause) <= _MAX_PAUSE:
            problems.append(
                f"{label}: pause must be a number in [0, {_MAX_PAUSE}] s, got {pause!r}"
            )
        if voice not in VOICES:
            problems.append(f"{label}: voice must be one of {list(VOICES)}, got {voice!r}")
        problems += _structure_problems(label, table, start)
        if not problems:
            for pid, ph in table.items():
                if ph.is_pause:
                    continue
                d = duration.get(pid)
                if d is None:
                    problems.append(f"{label}: {ph.kind} {pid!r}: no duration")
                elif not _is_number(d) or not 0.0 < float(d) < math.inf:
                    problems.append(
                        f"{label}: {ph.kind} {pid!r}: duration must be > 0 s, got {d!r}"
                    )
                elif ph.kind == "filler" and float(d) > MAX_FILLER:
                    problems.append(
                        f"{label}: filler {pid!r}: its clip lasts {float(d):.2f} s; a filler is "
                        f"at most {MAX_FILLER} s (make it a phrase)"
                    )
        reps = dict(repeats) if isinstance(repeats, Mapping) else {r.name: r for r in repeats}
        if not all(isinstance(r, Repeat) for r in reps.values()):
            problems.append(f"{label}: repeats must be Repeat objects, got {reps!r}")
        elif not problems:
            problems += [
                f"{label}: {ph.kind} {pid!r}: ids may not contain {SEP!r} (LangCtrl names the "
                "vertices it adds with it)"
                for pid, ph in table.items()
                if SEP in pid
            ]
            problems += repeat_problems(label, table, reps)
        if not isinstance(final_wait, bool):
            problems.append(f"{label}: final_wait must be true or false, got {final_wait!r}")
        legs = tuple(legs)
        own_legs = dict(leg_of or {})
        if not problems:
            problems += leg_problems(label, table, legs, own_legs)
        own_intents = dict(intents or {})
        problems += _intent_problems(label, table, own_intents)
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
        seg = segment_of(table, self.legs, leg, _topological_order(table))
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
        self.order: tuple[str, ...] = _topological_order(table)
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
        path = Path(path)
        try:
            source = path.read_text(encoding="utf-8")
        except (OSError, UnicodeDecodeError) as exc:
            reason = getattr(exc, "strerror", None) or exc
            raise PhraseGraphError(f"{path}: cannot read phrase graph: {reason}") from None
        import yaml

        from langenv.validation import yaml_text

        try:
            data = yaml.safe_load(yaml_text(source, path))
        except yaml.YAMLError as exc:
            raise PhraseGraphError(f"{path}: invalid YAML: {exc}") from None
        start, pause, voice, phrases = _parse(path, data)
        assert isinstance(data, dict)
        repeats, problems = parse_repeats(path, data.get("repeats"))
        legs, leg_of = _parse_legs(path, data, problems)
        intents = _parse_intents(path, data, problems)
        final_wait = data.get("final_wait", False)
        if not isinstance(final_wait, bool):
            problems.append(f"{path}: 'final_wait' must be true or false, got {final_wait!r}")
        if problems:
            raise PhraseGraphError("\n".join(problems))
        problems = _structure_problems(str(path), phrases, start)
        if not problems:
            problems = _unreachable_problems(str(path), phrases, start)
        if problems:
            raise PhraseGraphError("\n".join(problems))

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
            start,
            durations,
            pause=pause,
            voice=voice,
            path=path,
            repeats=repeats,
            final_wait=final_wait,
            legs=legs,
            leg_of=leg_of,
            intents=intents,
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
        return PhraseGraph(
            self.source_phrases,
            self.start,
            self.duration,
            pause=self.pause,
            voice=voice,
            path=self.path,
            repeats=self.repeats,
            final_wait=self.final_wait,
            legs=self.legs,
            leg_of=self.leg_of,
            intents=self.intent_of,
        )

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
        return _nearest(kids, self._mid, t_x)

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
            v = _nearest(kids, mid, left)
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
            w = _nearest(kids, mid, y)
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


def _nearest(kids: tuple[str, ...], mid: Mapping[str, float], x: float) -> str:
    """The paper's choice: the first of ``kids`` (non-empty) whose ``mid`` is nearest ``x``
    (mirrored, comparison for comparison, by :func:`langenv.speech.graph_kernels.nearest`)."""
    best = kids[0]
    best_err = abs(x - mid[best])
    for v in kids[1:]:
        err = abs(x - mid[v])
        if err < best_err:
            best, best_err = v, err
    return best


def _is_number(x: object) -> bool:
    return isinstance(x, int | float) and not isinstance(x, bool) and math.isfinite(x)


def _parse(path: Path, data: object) -> tuple[str, float, str, dict[str, Phrase]]:
    """Check the YAML document's shape; build the phrases (all problems at once)."""
    if not isinstance(data, dict):
        kind = "empty" if data is None else f"a {type(data).__name__}"
        raise PhraseGraphError(
            f"{path}: a phrase graph must be a mapping with 'start' and "
            f"'phrases', the file is {kind}"
        )
    problems: list[str] = []
    unknown = sorted(str(k) for k in data if k not in _TOP_KEYS)
    if unknown:
        problems.append(f"{path}: unknown key(s) {unknown}; allowed: {sorted(_TOP_KEYS)}")
    start = data.get("start")
    if not isinstance(start, str) or not start:
        problems.append(f"{path}: 'start' must be a phrase id, got {start!r}")
    pause = data.get("pause", DEFAULT_PAUSE)
    if not _is_number(pause) or not 0.0 <= float(pause) <= _MAX_PAUSE:
        problems.append(
            f"{path}: 'pause' must be a number of seconds in [0, {_MAX_PAUSE}], got {pause!r}"
        )
    voice = data.get("voice", "stretch")
    if voice not in VOICES:
        problems.append(f"{path}: 'voice' must be one of {list(VOICES)}, got {voice!r}")
    raw = data.get("phrases")
    phrases: dict[str, Phrase] = {}
    if not isinstance(raw, dict) or not raw:
        problems.append(f"{path}: 'phrases' must be a non-empty mapping of phrase id -> phrase")
        raw = {}
    for pid, spec in raw.items():
        if not isinstance(pid, str) or not pid:
            problems.append(f"{path}: phrase id {pid!r} must be a non-empty string (quote it)")
            continue
        ph, found = _parse_vertex(path, pid, spec)
        problems += found
        if ph is not None:
            phrases[pid] = ph
    if problems:
        raise PhraseGraphError("\n".join(problems))
    assert isinstance(start, str)
    return start, float(pause), str(voice), phrases


def _parse_legs(
    path: Path, data: dict[str, Any], problems: list[str]
) -> tuple[tuple[str, ...], dict[str, str]]:
    """The file's ``legs`` and each vertex's ``leg`` (problems appended, naming the file)."""
    raw = data.get("legs", [])
    if not isinstance(raw, list) or not all(isinstance(x, str) and x for x in raw):
        problems.append(f"{path}: 'legs' must be a list of leg names, got {raw!r}")
        raw = []
    leg_of: dict[str, str] = {}
    for pid, spec in (data.get("phrases") or {}).items():
        if isinstance(spec, dict) and "leg" in spec:
            leg = spec["leg"]
            if not isinstance(leg, str) or not leg:
                problems.append(f"{path}: vertex {pid!r}: 'leg' must be a leg name, got {leg!r}")
                continue
            leg_of[str(pid)] = leg
    return tuple(raw), leg_of


def _parse_intents(path: Path, data: dict[str, Any], problems: list[str]) -> dict[str, str]:
    """Each vertex's ``intent`` (problems appended, naming the file and the vertex)."""
    intents: dict[str, str] = {}
    for pid, spec in (data.get("phrases") or {}).items():
        if isinstance(spec, dict) and "intent" in spec:
            found = intent_problem(spec["intent"])
            if found:
                problems.append(f"{path}: vertex {pid!r}: {found}")
                continue
            intents[str(pid)] = spec["intent"]
    return intents


def _intent_problems(
    label: str, table: Mapping[str, Phrase], intents: Mapping[str, str]
) -> list[str]:
    """An intent on a vertex the graph lacks, on a filler or pause, or not in the vocabulary."""
    problems = []
    for pid, name in intents.items():
        ph = table.get(pid)
        if ph is None:
            problems.append(f"{label}: intent of {pid!r}: the graph has no such vertex")
        elif ph.kind != "phrase":
            problems.append(
                f"{label}: {ph.kind} {pid!r}: only a phrase carries an intent, got {name!r}"
            )
        elif intent_problem(name):
            problems.append(f"{label}: phrase {pid!r}: {intent_problem(name)}")
    return problems


def _parse_vertex(path: Path, pid: str, spec: object) -> tuple[Phrase | None, list[str]]:
    """One vertex of the YAML (phrase, filler or pause) and the problems found in it."""
    if not isinstance(spec, dict):
        return None, [
            f"{path}: phrase {pid!r}: must be a mapping with 'text' and/or 'audio' (or 'pause') "
            "and 'next'"
        ]
    is_pause = "pause" in spec
    filler = spec.get("filler", False)
    kind = "pause" if is_pause else ("filler" if filler is True else "phrase")
    where = f"{path}: {kind} {pid!r}"
    problems: list[str] = []
    bad = sorted(str(k) for k in spec if k not in _PHRASE_KEYS)
    if bad:
        problems.append(f"{where}: unknown key(s) {bad}; allowed: {sorted(_PHRASE_KEYS)}")
    if not isinstance(filler, bool):
        problems.append(f"{where}: 'filler' must be true or false, got {filler!r}")
    text = spec.get("text")
    audio = spec.get("audio")
    bounds = None
    if is_pause:
        for key in ("text", "audio", "filler"):
            if key in spec:
                problems.append(f"{where}: a pause is silence: it has no {key!r}")
        found = _bounds_problem(spec["pause"])
        if found:
            problems.append(f"{where}: {found}")
        else:
            bounds = (float(spec["pause"][0]), float(spec["pause"][1]))
    else:
        if text is not None and (not isinstance(text, str) or not text.strip()):
            problems.append(f"{where}: 'text' must be a non-empty string, got {text!r}")
        if audio is not None and (not isinstance(audio, str) or not audio.strip()):
            problems.append(f"{where}: 'audio' must be a file path, got {audio!r}")
        if text is None and audio is None:
            problems.append(
                f"{where}: no audio: give 'text' (spoken by TTS) or 'audio'"
                if kind == "filler"
                else f"{where}: has neither 'text' nor 'audio'"
            )
    if "next" not in spec:
        problems.append(f"{where}: missing 'next' (write next: [] for a final phrase)")
    nxt = spec.get("next")
    nxt = [] if nxt is None else [nxt] if isinstance(nxt, str) else nxt
    if not isinstance(nxt, list) or not all(isinstance(v, str) and v for v in nxt):
        problems.append(f"{where}: 'next' must be a list of phrase ids, got {spec.get('next')!r}")
    if problems:
        return None, problems
    audio_path = None if audio is None else (path.parent / Path(audio).expanduser())
    return (
        Phrase(
            id=pid,
            text=None if is_pause else text,
            audio=None if is_pause else audio_path,
            next=tuple(nxt),
            kind=kind,
            bounds=bounds,
        ),
        [],
    )


def _structure_problems(label: str, phrases: Mapping[str, Phrase], start: object) -> list[str]:
    """Unknown ids, duplicate edges, cycles, dead ends and misplaced pauses, one message per
    problem."""
    problems: list[str] = []
    if not phrases:
        return [f"{label}: the graph has no phrases"]
    if not isinstance(start, str) or start not in phrases:
        problems.append(f"{label}: start phrase {start!r} is not a phrase of this graph")
    for pid, ph in phrases.items():
        seen: set[str] = set()
        for v in ph.next:
            if v not in phrases:
                problems.append(
                    f"{label}: phrase {pid!r}: next {v!r} is not a phrase of this graph"
                )
            if v in seen:
                problems.append(f"{label}: phrase {pid!r}: next lists {v!r} twice")
            seen.add(v)
    if problems:
        return problems
    # cycles: strongly connected components with more than one phrase, or a self-loop
    for comp in _strongly_connected(phrases):
        if len(comp) > 1 or comp[0] in phrases[comp[0]].next:
            cycle = _a_cycle(phrases, set(comp))
            problems.append(
                f"{label}: {phrases[cycle[0]].kind} {cycle[0]!r}: on a cycle "
                f"{' -> '.join(repr(c) for c in cycle)}"
                + (
                    f" (phrases on cycles here: {sorted(comp)})"
                    if len(comp) > len(cycle) - 1
                    else ""
                )
            )
    # dead ends: phrases from which no terminal can be reached
    parents: dict[str, list[str]] = {pid: [] for pid in phrases}
    for pid, ph in phrases.items():
        for v in ph.next:
            parents[v].append(pid)
    alive = {pid for pid, ph in phrases.items() if not ph.next}
    stack = list(alive)
    while stack:
        for w in parents[stack.pop()]:
            if w not in alive:
                alive.add(w)
                stack.append(w)
    for pid in phrases:
        if pid not in alive:
            problems.append(
                f"{label}: {phrases[pid].kind} {pid!r}: dead end, no final phrase can be reached"
            )
    assert isinstance(start, str)
    problems += _pause_problems(label, phrases, start)
    return problems


def _unreachable_problems(label: str, phrases: Mapping[str, Phrase], start: str) -> list[str]:
    """Vertices that no speech from ``start`` says (an error in a graph file)."""
    problems: list[str] = []
    seen = {start}
    stack = [start]
    while stack:
        for v in phrases[stack.pop()].next:
            if v not in seen:
                seen.add(v)
                stack.append(v)
    for pid, ph in phrases.items():
        if pid not in seen:
            problems.append(
                f"{label}: {ph.kind} {pid!r}: unreachable, no speech from {start!r} says it"
            )
    return problems


def _pause_problems(label: str, phrases: Mapping[str, Phrase], start: str) -> list[str]:
    """Pauses where silence cannot be: at the start, at the end, right after another pause."""
    problems: list[str] = []
    for pid, ph in phrases.items():
        if not ph.is_pause:
            continue
        if pid == start:
            problems.append(f"{label}: pause {pid!r}: the speech cannot start with a pause")
        if not ph.next:
            problems.append(
                f"{label}: pause {pid!r}: the speech cannot end with a pause (it ends with its "
                "last word)"
            )
        for v in ph.next:
            if phrases[v].is_pause:
                problems.append(
                    f"{label}: pause {v!r}: follows pause {pid!r}; merge the two into one"
                )
    return problems


def _strongly_connected(phrases: Mapping[str, Phrase]) -> list[list[str]]:
    """Tarjan's algorithm, iterative (graphs can be deep)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    on_stack: set[str] = set()
    stack: list[str] = []
    comps: list[list[str]] = []
    counter = 0
    for root in phrases:
        if root in index:
            continue
        work: list[tuple[str, int]] = [(root, 0)]
        while work:
            v, i = work.pop()
            if i == 0:
                index[v] = low[v] = counter
                counter += 1
                stack.append(v)
                on_stack.add(v)
            kids = phrases[v].next
            recurse = False
            while i < len(kids):
                w = kids[i]
                i += 1
                if w not in index:
                    work.append((v, i))
                    work.append((w, 0))
                    recurse = True
                    break
                if w in on_stack:
                    low[v] = min(low[v], index[w])
            if recurse:
                continue
            if low[v] == index[v]:
                comp = []
                while True:
                    w = stack.pop()
                    on_stack.discard(w)
                    comp.append(w)
                    if w == v:
                        break
                comps.append(comp)
            if work:
                parent = work[-1][0]
                low[parent] = min(low[parent], low[v])
    return comps


def _a_cycle(phrases: Mapping[str, Phrase], comp: set[str]) -> list[str]:
    """One concrete cycle inside a strongly connected component, first phrase repeated last."""
    u = min(comp)
    walk = [u]
    pos = {u: 0}
    while True:
        v = next(w for w in phrases[walk[-1]].next if w in comp)
        if v in pos:
            return [*walk[pos[v] :], v]
        pos[v] = len(walk)
        walk.append(v)


def _topological_order(phrases: Mapping[str, Phrase]) -> tuple[str, ...]:
    """Kahn's algorithm (the graph is known to be acyclic), stable in definition order."""
    indeg = dict.fromkeys(phrases, 0)
    for ph in phrases.values():
        for v in ph.next:
            indeg[v] += 1
    ready = [pid for pid in phrases if indeg[pid] == 0]
    order: list[str] = []
    i = 0
    while i < len(ready):
        u = ready[i]
        i += 1
        order.append(u)
        for v in phrases[u].next:
            indeg[v] -= 1
            if indeg[v] == 0:
                ready.append(v)
    return tuple(order)
