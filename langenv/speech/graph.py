"""Phrase graphs: what the robot may say, as a DAG of phrases, and the paper's choice rule.

A phrase graph (SPEC §4) is a directed acyclic graph whose vertices are phrases (a text and/or a
recorded clip) and whose edges say which phrase may follow which. Speech starts at ``start`` and
ends at a terminal phrase (no ``next``). Between two phrases there is ``pause`` seconds of silence
at audio pace 1; there is none after the final phrase: the speech is over when its last word ends.

Time conventions (all at audio pace ``a = 1``, in seconds):

* ``duration[u]``: length of ``u``'s clip, measured from the audio itself;
* ``slot(u)``: from the start of ``u`` to the start of the phrase after it, i.e.
  ``duration[u] + pause`` (just ``duration[u]`` for a terminal phrase);
* ``t_min(u)``, ``t_max(u)``: shortest/longest speech from the start of ``u`` to the end of the
  speech, computed in reverse topological order:
  ``t_min(u) = slot(u) + min over children v of t_min(v)`` (``duration[u]`` for a terminal).

The next phrase is chosen when the current phrase's slot ends (its pause is over), with the paper's
rule ``argmin over children v of |t_x - (t_min(v) + t_max(v)) / 2|`` (ties: the child listed
first in ``next``); at that instant the remaining speech is exactly ``t_min(v)..t_max(v)``, which is
what the rule compares with the motion's time to completion ``t_x``.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from pathlib import Path
from types import MappingProxyType
from typing import Any

from langenv.errors import AudioError, ConfigError, PhraseGraphError
from langenv.speech.audio import ClipLibrary

__all__ = [
    "DEFAULT_PAUSE",
    "GRAPHS_DIR",
    "SHIPPED_GRAPHS",
    "Phrase",
    "PhraseGraph",
    "default_graph_path",
    "graph_path",
]

DEFAULT_PAUSE = 1.0
"""Silence between two phrases at a = 1 (s) when a graph file gives no ``pause`` (SPEC §2)."""

GRAPHS_DIR = Path(__file__).resolve().parents[1] / "assets" / "graphs"
"""Directory of the phrase graphs shipped with the package."""

SHIPPED_GRAPHS: Mapping[str, Path] = MappingProxyType(
    {
        "lc": GRAPHS_DIR / "lc.yaml",
        "lc-noap": GRAPHS_DIR / "lc_noap.yaml",
        # AC says the same single wording as LC-noAP, at a = 1 (the study's AC and LC-noAP
        # speech both lasted about 13.4 s): one prerecorded utterance with its pauses.
        "ac": GRAPHS_DIR / "lc_noap.yaml",
    }
)
"""The shipped phrase graphs of the default exercise, by name (the one place names resolve)."""

_TOP_KEYS = frozenset({"start", "pause", "phrases"})
_PHRASE_KEYS = frozenset({"text", "audio", "next"})
_MAX_PAUSE = 10.0


def default_graph_path(name: str) -> Path:
    """Path of a shipped phrase graph.

    Args:
        name: ``"lc"``, ``"lc-noap"`` (or ``"lc_noap"``) or ``"ac"``.

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
    """One vertex of a phrase graph.

    Attributes:
        id: Unique name of the phrase in its graph.
        text: What it says (used for TTS when ``audio`` is None, and for subtitles).
        audio: Recorded clip (absolute path, or relative to the working directory); None: TTS.
        next: Ids of the phrases that may follow, in preference order for ties; empty: terminal.
    """

    id: str
    text: str | None
    audio: Path | None
    next: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        if not isinstance(self.id, str) or not self.id:
            raise PhraseGraphError(f"Phrase.id must be a non-empty str, got {self.id!r}")
        if self.text is not None and (not isinstance(self.text, str) or not self.text.strip()):
            raise PhraseGraphError(f"phrase {self.id!r}: text must be a non-empty str or None")
        if self.audio is not None and not isinstance(self.audio, Path):
            object.__setattr__(self, "audio", Path(self.audio))
        if self.text is None and self.audio is None:
            raise PhraseGraphError(f"phrase {self.id!r}: has neither 'text' nor 'audio'")
        nxt = (self.next,) if isinstance(self.next, str) else tuple(self.next)
        if not all(isinstance(v, str) for v in nxt):
            raise PhraseGraphError(f"phrase {self.id!r}: next must be a list of phrase ids")
        object.__setattr__(self, "next", nxt)

    @property
    def terminal(self) -> bool:
        """True when nothing follows this phrase."""
        return not self.next


class PhraseGraph:
    """A validated phrase DAG with clip durations, ``t_min``/``t_max`` and the choice rule.

    Build one with :meth:`load` from a YAML file (SPEC §4), or directly from phrases and
    durations (tests, programmatic graphs).

    Args:
        phrases: The phrases (a mapping id -> phrase, or an iterable of phrases).
        start: Id of the first phrase.
        duration: Clip length at a = 1 of every phrase (s, > 0).
        pause: Silence between two phrases at a = 1 (s, in [0, 10]).
        path: File the graph came from, named in error messages (None: built in memory).

    Raises:
        PhraseGraphError: listing every problem, one per line, each naming the file and the
            phrase: unknown ``start`` or ``next`` id, duplicate ``next`` entries, a cycle (with the
            phrases on it), a phrase that cannot reach a terminal, a missing or bad duration, a bad
            pause.
    """

    def __init__(
        self,
        phrases: Mapping[str, Phrase] | Iterable[Phrase],
        start: str,
        duration: Mapping[str, float],
        *,
        pause: float = DEFAULT_PAUSE,
        path: str | Path | None = None,
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
                problems.append(f"{label}: phrase {ph.id!r}: defined twice")
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
        problems += _structure_problems(label, table, start)
        if not problems:
            for pid in table:
                d = duration.get(pid)
                if d is None:
                    problems.append(f"{label}: phrase {pid!r}: no duration")
                elif not _is_number(d) or not 0.0 < float(d) < math.inf:
                    problems.append(f"{label}: phrase {pid!r}: duration must be > 0 s, got {d!r}")
        if problems:
            raise PhraseGraphError("\n".join(problems))

        self.start: str = start
        self.pause: float = float(pause)
        self.phrases: Mapping[str, Phrase] = MappingProxyType(table)
        self.duration: Mapping[str, float] = MappingProxyType(
            {pid: float(duration[pid]) for pid in table}
        )
        self.order: tuple[str, ...] = _topological_order(table)
        """Phrase ids in topological order (every phrase before the phrases that follow it)."""
        self._children = {pid: ph.next for pid, ph in table.items()}
        self._slot = {
            pid: self.duration[pid] + (self.pause if ph.next else 0.0) for pid, ph in table.items()
        }
        t_min: dict[str, float] = {}
        t_max: dict[str, float] = {}
        for pid in reversed(self.order):
            kids = self._children[pid]
            if kids:
                t_min[pid] = self._slot[pid] + min(t_min[v] for v in kids)
                t_max[pid] = self._slot[pid] + max(t_max[v] for v in kids)
            else:
                t_min[pid] = t_max[pid] = self._slot[pid]
        self._t_min = t_min
        self._t_max = t_max
        self._mid = {pid: 0.5 * (t_min[pid] + t_max[pid]) for pid in table}
        self.max_children: int = max(len(k) for k in self._children.values())
        """Largest number of children of any phrase (0 for a single-phrase graph)."""

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
                ``pause``, unknown ``start``/``next`` ids, a phrase with neither ``text`` nor
                ``audio``, a cycle, a phrase that cannot reach a terminal, a missing or
                unreadable audio file.
        """
        path = Path(path)
        try:
            source = path.read_text(encoding="utf-8")
        except (OSError, UnicodeDecodeError) as exc:
            reason = getattr(exc, "strerror", None) or exc
            raise PhraseGraphError(f"{path}: cannot read phrase graph: {reason}") from None
        import yaml

        try:
            data = yaml.safe_load(source)
        except yaml.YAMLError as exc:
            raise PhraseGraphError(f"{path}: invalid YAML: {exc}") from None
        start, pause, phrases = _parse(path, data)
        problems = _structure_problems(str(path), phrases, start)
        if problems:
            raise PhraseGraphError("\n".join(problems))

        if clips is None:
            clips = ClipLibrary()
        durations: dict[str, float] = {}
        for pid, ph in phrases.items():
            if ph.audio is not None and not ph.audio.is_file():
                problems.append(f"{path}: phrase {pid!r}: audio file {ph.audio} does not exist")
                continue
            try:
                durations[pid] = clips.duration(ph)
            except AudioError as exc:  # its message names the audio file and the phrase
                problems.append(f"{path}: {exc}")
        if problems:
            raise PhraseGraphError("\n".join(problems))
        return cls(phrases, start, durations, pause=pause, path=path)

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

        ``duration[u] + pause``; ``duration[u]`` alone for a terminal phrase.
        """
        try:
            return self._slot[u]
        except KeyError:
            raise PhraseGraphError(f"{self._label}: no phrase {u!r}") from None

    def t_min(self, u: str) -> float:
        """Shortest speech from the start of ``u`` to the end, pauses included, at a = 1 (s)."""
        try:
            return self._t_min[u]
        except KeyError:
            raise PhraseGraphError(f"{self._label}: no phrase {u!r}") from None

    def t_max(self, u: str) -> float:
        """Longest speech from the start of ``u`` to the end, pauses included, at a = 1 (s)."""
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
        mid = self._mid
        best = kids[0]
        best_err = abs(t_x - mid[best])
        for v in kids[1:]:
            err = abs(t_x - mid[v])
            if err < best_err:
                best, best_err = v, err
        return best

    def eta(self, u: str, remaining_in_u: float, t_x: float) -> float:
        """Speech time to completion ``t_a`` at a = 1 (SPEC §1).

        The rest of the current phrase's slot plus the slots of the phrases that repeated use of
        :meth:`choose` would take, each choice evaluated with the ``t_x`` left at that moment
        (``t_x`` minus the base-pace time until the choice).

        Args:
            u: The current phrase.
            remaining_in_u: Base-pace time until ``u``'s slot ends (its pause included) (s).
            t_x: Motion time to completion now (s).

        Returns:
            Seconds of speech left at a = 1 (without a trailing pause after the final phrase).
        """
        kids = self.children(u)
        total = remaining_in_u
        left = t_x - remaining_in_u
        slot, mid, children = self._slot, self._mid, self._children
        while kids:
            v = kids[0]
            err = abs(left - mid[v])
            for w in kids[1:]:
                e = abs(left - mid[w])
                if e < err:
                    v, err = w, e
            total += slot[v]
            left -= slot[v]
            kids = children[v]
        return total

    def shortest_path(self, u: str | None = None) -> tuple[str, ...]:
        """A path from ``u`` (default: start) to a terminal whose speech lasts ``t_min(u)``."""
        return self._extreme_path(self.start if u is None else u, self._t_min, min)

    def longest_path(self, u: str | None = None) -> tuple[str, ...]:
        """A path from ``u`` (default: start) to a terminal whose speech lasts ``t_max(u)``."""
        return self._extreme_path(self.start if u is None else u, self._t_max, max)

    def path_length(self, path: Iterable[str]) -> float:
        """Speech length of a path of phrases at a = 1 (s): slots, without a trailing pause.

        Raises:
            PhraseGraphError: if ``path`` is empty, names an unknown phrase or skips an edge.
        """
        ids = list(path)
        if not ids:
            raise PhraseGraphError(f"{self._label}: empty path")
        for u, v in itertools.pairwise(ids):
            if v not in self.children(u):
                raise PhraseGraphError(f"{self._label}: phrase {v!r} does not follow {u!r}")
        last = ids[-1]
        return sum(self.slot(u) for u in ids[:-1]) + self.duration[last]

    def count_paths(self, u: str | None = None) -> int:
        """Number of distinct paths from ``u`` (default: start) to a terminal."""
        counts: dict[str, int] = {}
        for pid in reversed(self.order):
            kids = self._children[pid]
            counts[pid] = sum(counts[v] for v in kids) if kids else 1
        return counts[self.start if u is None else u]

    def paths(self, u: str | None = None, *, limit: int = 100_000) -> list[tuple[str, ...]]:
        """Every path from ``u`` (default: start) to a terminal, depth first, children in order.

        Raises:
            ConfigError: if there are more than ``limit`` paths (use :meth:`count_paths`).
        """
        root = self.start if u is None else u
        n = self.count_paths(root)
        if n > limit:
            raise ConfigError(f"paths: {n} paths from {root!r} exceed limit={limit}")
        out: list[tuple[str, ...]] = []
        stack: list[tuple[str, ...]] = [(root,)]
        while stack:
            p = stack.pop()
            kids = self._children[p[-1]]
            if not kids:
                out.append(p)
            for v in reversed(kids):
                stack.append((*p, v))
        return out

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
            f"pause={self.pause}, speech {self.t_min(self.start):.2f}-"
            f"{self.t_max(self.start):.2f} s)"
        )

    # ------------------------------------------------------------------ internals
    @property
    def _label(self) -> str:
        return str(self.path) if self.path is not None else "<phrase graph>"

    def _extreme_path(self, u: str, table: dict[str, float], pick: Any) -> tuple[str, ...]:
        self.children(u)  # validates u
        path = [u]
        while kids := self._children[path[-1]]:
            best = pick(table[v] for v in kids)
            path.append(next(v for v in kids if table[v] == best))
        return tuple(path)


def _is_number(x: object) -> bool:
    return isinstance(x, int | float) and not isinstance(x, bool) and math.isfinite(x)


def _parse(path: Path, data: object) -> tuple[str, float, dict[str, Phrase]]:
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
    raw = data.get("phrases")
    phrases: dict[str, Phrase] = {}
    if not isinstance(raw, dict) or not raw:
        problems.append(f"{path}: 'phrases' must be a non-empty mapping of phrase id -> phrase")
        raw = {}
    for pid, spec in raw.items():
        if not isinstance(pid, str) or not pid:
            problems.append(f"{path}: phrase id {pid!r} must be a non-empty string (quote it)")
            continue
        where = f"{path}: phrase {pid!r}"
        if not isinstance(spec, dict):
            problems.append(f"{where}: must be a mapping with 'text' and/or 'audio' and 'next'")
            continue
        bad = sorted(str(k) for k in spec if k not in _PHRASE_KEYS)
        if bad:
            problems.append(f"{where}: unknown key(s) {bad}; allowed: {sorted(_PHRASE_KEYS)}")
        text = spec.get("text")
        audio = spec.get("audio")
        ok = True
        if text is not None and (not isinstance(text, str) or not text.strip()):
            problems.append(f"{where}: 'text' must be a non-empty string, got {text!r}")
            ok = False
        if audio is not None and (not isinstance(audio, str) or not audio.strip()):
            problems.append(f"{where}: 'audio' must be a file path, got {audio!r}")
            ok = False
        if text is None and audio is None:
            problems.append(f"{where}: has neither 'text' nor 'audio'")
            ok = False
        if "next" not in spec:
            problems.append(f"{where}: missing 'next' (write next: [] for a final phrase)")
            ok = False
        nxt = spec.get("next")
        nxt = [] if nxt is None else [nxt] if isinstance(nxt, str) else nxt
        if not isinstance(nxt, list) or not all(isinstance(v, str) and v for v in nxt):
            problems.append(f"{where}: 'next' must be a list of phrase ids, got {spec['next']!r}")
            ok = False
        if not ok:
            continue
        audio_path = None if audio is None else (path.parent / Path(audio).expanduser())
        phrases[pid] = Phrase(id=pid, text=text, audio=audio_path, next=tuple(nxt))
    if problems:
        raise PhraseGraphError("\n".join(problems))
    assert isinstance(start, str)
    return start, float(pause), phrases


def _structure_problems(label: str, phrases: Mapping[str, Phrase], start: object) -> list[str]:
    """Unknown ids, duplicate edges, cycles and dead ends, one message per problem."""
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
                f"{label}: phrase {cycle[0]!r}: on a cycle {' -> '.join(repr(c) for c in cycle)}"
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
            problems.append(f"{label}: phrase {pid!r}: dead end, no final phrase can be reached")
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
