"""Phrase graphs written from plain text: ``langctrl speech author SCRIPT.txt``.

A *script* says what the robot may say, one line per step of the exercise, in order::

    # shoulder external rotation (lines starting with '#' are comments)
    @pause 0.4
    I want you to move your hand away from your body this way.
    (pause 0.3-1.5)
    [Glide really smoothly.] | Slide, slide, slide.
    {okay|so} I want you to retract your arm. | Move your arm back.
    And you're done.

* A line is one step; the speech says one of its *alternatives* (separated by ``|``) after one
  of the previous step's, so every alternative of a line may follow every alternative of the line
  before it. The first line is the start: exactly one wording.
* ``[...]`` marks words that may be left out: ``[Good,] and to the middle.`` is two wordings.
  An alternative that is all optional lets the speech skip the step.
* ``(pause MIN-MAX)`` (seconds, e.g. ``(pause 0.5-2)``; ``(pause 1)`` for a fixed length) is a
  pause vertex: silence whose length the controller chooses within the bounds. It may stand on
  its own line (between two steps) or inside an alternative (between two phrases).
* ``{okay|so}`` is a choice of fillers the speech may say or skip before what follows.
* ``(repeat N)`` or ``(repeat N, gap MIN-MAX)`` at the end of a line lets the speech say the line
  again while the motion lasts: after any of its wordings and a silence of ``MIN``-``MAX`` s (on
  top of ``@pause``; default 1-3 s), any of them again, at most ``N`` times in a row (2-20), e.g.
  ``Keep going. | Nice and slow. | You're doing well. (repeat 4, gap 1-3)``. The line must end
  with its words (no pause or filler last). See :mod:`langenv.speech.repeat`.
* The last phrase waits for the motion: when the words before it are over early the speech is
  silent, then says it so that it ends with the motion (``final_wait: true`` in the YAML; no line
  needed). ``@final-wait off`` (before the first step) makes the graph end as the paper's did,
  the last phrase said straight after the one before it.
* ``<INTENT>`` right after a wording's words marks what the wording asks of the person, one of
  :data:`~langenv.speech.intents.INTENTS` (``[Keep going.]<encourage> | [Relax your arm.]<relax>``);
  the YAML keeps it (``intent:``) and a person who listens responds to it
  (:mod:`langenv.users.listening`). Only a pause, a filler or the end of the alternative may
  follow it.
* ``@leg NAME`` on its own line starts the lines spoken for the exercise's leg ``NAME`` (the
  names in the exercise file): the speech keeps each leg's words in step with that leg of the
  motion. Marks follow the exercise's order, each leg once; when a script has marks, every step
  comes after one (a pause line right after a mark belongs to that leg). A script without marks
  is aligned with the motion at its end only.
* ``@pause S`` (once, before the first step) sets the silence after every clip (default 1 s).
* ``@voice natural`` (before the first step) voices the script as a person speaks: each clip at
  its natural rate or faster, waiting in silence at its end when the person is slow, instead of
  the paper's time-stretched voice (``@voice stretch``, the default); see
  :mod:`langenv.speech.voice`.

:func:`parse_script` turns a script into a :class:`Script` (its vertices, with the line and column
each came from), :func:`graph_yaml` writes the YAML of a phrase graph (SPEC §4), deterministic
byte for byte, and :func:`author` does both, then synthesises and times every clip (the TTS
cache) through :meth:`PhraseGraph.load <langenv.speech.graph.PhraseGraph.load>`, which validates
the graph. Errors are :class:`~langenv.errors.ScriptError` naming the file, the line and the
column; nothing is written unless the whole graph is valid.
"""

from __future__ import annotations

import json
import os
import re
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import yaml

from langenv.errors import PhraseGraphError, ScriptError
from langenv.files import temp_file
from langenv.speech.audio import ClipLibrary
from langenv.speech.graph import PhraseGraph
from langenv.speech.intents import INTENTS, intent_problem
from langenv.speech.phrase import DEFAULT_PAUSE, MAX_PAUSE
from langenv.speech.repeat import DEFAULT_GAP, MAX_REPEAT
from langenv.speech.voice import VOICES

__all__ = ["Script", "ScriptRepeat", "Vertex", "author", "graph_yaml", "parse_script"]

_PAUSE_RE = re.compile(r"pause\s+([0-9]*\.?[0-9]+)(?:\s*-\s*([0-9]*\.?[0-9]+))?\s*$")
_REPEAT_AT_END = re.compile(r"\(\s*repeat\b([^()]*)\)\s*$")
_REPEAT_RE = re.compile(
    r"\s*(\d+)\s*(?:,?\s*gap\s+([0-9]*\.?[0-9]+)(?:\s*-\s*([0-9]*\.?[0-9]+))?)?\s*$"
)
_OPEN = {"[": "]", "{": "}", "(": ")", "<": ">"}
_CLOSE = {v: k for k, v in _OPEN.items()}


@dataclass
class Vertex:
    """A vertex of the graph a script describes.

    Attributes:
        id: Its id in the YAML.
        kind: ``"phrase"``, ``"filler"`` or ``"pause"``.
        text: What it says (None for a pause).
        bounds: A pause's ``(min, max)`` (s).
        line, column: Where the script wrote it (1-based).
        next: Ids of the vertices that may follow.
        leg: The leg whose lines it is in (``@leg``); None in a script without marks.
        intent: What the wording asks of the person (``<INTENT>``,
            :data:`~langenv.speech.intents.INTENTS`); None without a mark.
    """

    id: str
    kind: str
    text: str | None
    bounds: tuple[float, float] | None
    line: int
    column: int
    next: list[str] = field(default_factory=list)
    leg: str | None = None
    intent: str | None = None


@dataclass(frozen=True)
class ScriptRepeat:
    """A line that may be said again: ``(repeat N, gap MIN-MAX)``.

    Attributes:
        name: The repeat's name in the YAML (``again_LINE``).
        phrases: Ids of the line's wordings.
        times: Most sayings in a row.
        gap: Silence between two sayings (s).
        line, column: Where the script wrote it (1-based).
    """

    name: str
    phrases: tuple[str, ...]
    times: int
    gap: tuple[float, float]
    line: int
    column: int


@dataclass
class Script:
    """A parsed script: its vertices in order (the first is the start), the clip pause, the
    voice, its repeats, whether the last phrase waits for the motion, and its ``@leg`` marks
    (leg name -> ``(line, column)``, in script order; empty: a script without marks)."""

    path: Path
    pause: float
    vertices: dict[str, Vertex]
    voice: str = "stretch"
    repeats: list[ScriptRepeat] = field(default_factory=list)
    final_wait: bool = True
    marks: dict[str, tuple[int, int]] = field(default_factory=dict)

    @property
    def legs(self) -> tuple[str, ...]:
        """The legs the script marks, in script order."""
        return tuple(self.marks)

    @property
    def start(self) -> str:
        """Id of the first vertex."""
        return next(iter(self.vertices))

    def where(self, vertex: str) -> str:
        """``FILE:LINE:COL`` of a vertex."""
        v = self.vertices[vertex]
        return f"{self.path}:{v.line}:{v.column}"


# ---------------------------------------------------------------------------------- tokens
@dataclass(frozen=True)
class _Unit:
    """One unit of an alternative: a phrase (its wordings), a pause or a filler choice."""

    kind: str  # "phrase", "pause", "filler"
    column: int
    words: tuple[str, ...] = ()  # phrase: its wordings ("" = left out); filler: the fillers
    bounds: tuple[float, float] | None = None
    intent: str | None = None  # phrase: the <INTENT> after its words


class _Line:
    """Splits and reads one script line, raising errors that name its line and column."""

    def __init__(self, path: Path, number: int, text: str) -> None:
        self.path, self.number, self.text = path, number, text

    def error(self, column: int, message: str) -> ScriptError:
        return ScriptError(f"{self.path}:{self.number}:{column}: {message}")

    def alternatives(self) -> list[tuple[int, str]]:
        """``(column, text)`` of each ``|``-separated alternative (``|`` inside ``{}`` kept)."""
        out: list[tuple[int, str]] = []
        depth: list[tuple[str, int]] = []
        start = 0
        for i, ch in enumerate(self.text):
            if ch in _OPEN:
                if depth:
                    raise self.error(i + 1, f"{ch!r} inside {depth[-1][0]!r}: brackets do not nest")
                depth.append((ch, i + 1))
            elif ch in _CLOSE:
                if not depth or depth[-1][0] != _CLOSE[ch]:
                    raise self.error(i + 1, f"{ch!r} closes nothing")
                depth.pop()
            elif ch == "|" and not depth:
                out.append((start + 1, self.text[start:i]))
                start = i + 1
        if depth:
            ch, col = depth[-1]
            raise self.error(col, f"{ch!r} is not closed (expected {_OPEN[ch]!r})")
        out.append((start + 1, self.text[start:]))
        for col, alt in out:
            if not alt.strip():
                raise self.error(col, "empty alternative (two '|' in a row, or one at an end)")
        return out

    def units(self, column: int, alt: str) -> list[_Unit]:
        """The units of one alternative starting at ``column``."""
        units: list[_Unit] = []
        pieces: list[tuple[str, bool]] = []  # (text, optional) of the phrase being read
        piece_col = 0
        marked = 0  # the column of the <INTENT> that ended the last phrase (0: none since)
        i = 0

        def flush(intent: str | None = None) -> None:
            nonlocal pieces
            if pieces:
                words = _wordings(pieces)
                for w in words:
                    if w and not re.search(r"[^\W\d_]", w):
                        raise self.error(piece_col, f"{w!r} has no words to say")
                if any(words):
                    units.append(_Unit("phrase", piece_col, tuple(dict.fromkeys(words)), None,
                                       intent))  # fmt: skip
            pieces = []

        while i < len(alt):
            ch = alt[i]
            col = column + i
            if ch in _OPEN:
                end = alt.index(_OPEN[ch], i)
                inner = alt[i + 1 : end]
                if ch == "<":
                    marked = self._intent(col, inner, bool(pieces), marked)
                    flush(inner.strip())
                    i = end + 1
                    continue
                if ch == "[" and marked:
                    raise self._after_intent(marked, col)
                if ch == "[":
                    if not inner.strip():
                        raise self.error(
                            col, "empty '[]': put the words that may be left out in it"
                        )
                    if not pieces:
                        piece_col = col
                    pieces.append((inner, True))
                else:
                    flush()
                    marked = 0
                    units.append(
                        self._pause(col, inner) if ch == "(" else self._fillers(col, inner)
                    )
                i = end + 1
                continue
            j = i
            while j < len(alt) and alt[j] not in _OPEN:
                j += 1
            text = alt[i:j]
            if text.strip() and marked:
                raise self._after_intent(marked, column + i + len(text) - len(text.lstrip()))
            if text.strip() and not pieces:
                piece_col = column + i + (len(text) - len(text.lstrip()))
            if text.strip() or pieces:  # whitespace between two bracketed parts separates them
                pieces.append((text, False))
            i = j
        flush()
        return units

    def _intent(self, col: int, inner: str, words: bool, marked: int) -> int:
        """Check the ``<INTENT>`` at ``col`` (after words when ``words``); returns ``col``."""
        if marked:
            raise self.error(col, f"a wording carries one intent (it has one at column {marked})")
        if not words:
            raise self.error(
                col, "an intent follows a wording's words, e.g. '[Keep going.]<encourage>'"
            )
        name = inner.strip()
        if not name:
            raise self.error(col, f"empty '<>': write one intent, one of {', '.join(INTENTS)}")
        problem = intent_problem(name)
        if problem:
            raise self.error(col + 1 + len(inner) - len(inner.lstrip()), problem)
        return col

    def _after_intent(self, marked: int, col: int) -> ScriptError:
        return self.error(
            col,
            f"words after the intent of column {marked}: an intent ends its wording (only a "
            "pause, a filler or '|' may follow it)",
        )

    def _pause(self, col: int, inner: str) -> _Unit:
        m = _PAUSE_RE.match(inner.strip())
        if m is None:
            raise self.error(
                col,
                f"'({inner})' is not a pause; write (pause MIN-MAX) in seconds, e.g. (pause 0.5-2)",
            )
        lo = float(m.group(1))
        hi = float(m.group(2)) if m.group(2) is not None else lo
        if lo > hi:
            raise self.error(col, f"pause bounds are reversed: {lo:g} > {hi:g}")
        if hi > MAX_PAUSE:
            raise self.error(col, f"a pause lasts at most {MAX_PAUSE:g} s, got {hi:g}")
        return _Unit("pause", col, bounds=(lo, hi))

    def _fillers(self, col: int, inner: str) -> _Unit:
        words = [w.strip() for w in inner.split("|")]
        if not inner.strip() or any(not w for w in words):
            raise self.error(
                col, f"'{{{inner}}}': fillers are words separated by '|', e.g. {{okay|so}}"
            )
        for w in words:
            if not re.search(r"[^\W\d_]", w):
                raise self.error(col, f"filler {w!r} has no word to say")
        return _Unit("filler", col, tuple(dict.fromkeys(_capital(w) for w in words)))


def _wordings(pieces: list[tuple[str, bool]]) -> list[str]:
    """Every wording of a run of text pieces, optional ones with and without (in that order)."""
    out = [""]
    for text, optional in pieces:
        out = [w + text for w in out] + ([*out] if optional else [])
    return [_capital(" ".join(w.split())) for w in out]


def _capital(text: str) -> str:
    return text[:1].upper() + text[1:] if text else text


_FILLER_WORDS = frozenset(
    "i im a an and are gonna let me the this to we you your youre".split()
)  # left out of vertex ids, which name a phrase by its first words that say something


def _slug(text: str, words: int = 3) -> str:
    tokens = re.findall(r"[a-z0-9]+", text.lower().replace("'", ""))
    content = [t for t in tokens if t not in _FILLER_WORDS] or tokens
    return "_".join(content[:words]) or "v"


# ---------------------------------------------------------------------------------- parsing
class _Builder:
    """Builds the vertices step by step, keeping the *frontier*: the vertices whose successors
    the next unit provides."""

    def __init__(self, path: Path) -> None:
        self.path = path
        self.vertices: dict[str, Vertex] = {}
        self.leg: str | None = None  # the leg of the lines being read (the last @leg mark)

    def add(self, kind: str, text: str | None, bounds: tuple[float, float] | None, line: int,
            col: int, parents: list[str], intent: str | None = None) -> str:  # fmt: skip
        base = (
            f"pause_{line}" if kind == "pause" else _slug(text or "", 1 if kind == "filler" else 3)
        )
        vid, k = base, 2
        while vid in self.vertices:
            vid, k = f"{base}_{k}", k + 1
        self.vertices[vid] = Vertex(vid, kind, text, bounds, line, col, leg=self.leg,
                                    intent=intent)  # fmt: skip
        for p in parents:
            nxt = self.vertices[p].next
            if vid not in nxt:
                nxt.append(vid)
        return vid

    def unit(self, line: _Line, unit: _Unit, frontier: list[str]) -> list[str]:
        """Attach ``unit`` after ``frontier``; returns the new frontier."""
        if not frontier:
            if unit.kind != "phrase" or len(unit.words) != 1 or "" in unit.words:
                raise line.error(
                    unit.column,
                    "the speech starts with one wording: the first step must be a single phrase "
                    "(no alternatives, optional words, pauses or fillers before it)",
                )
            return [
                self.add("phrase", unit.words[0], None, line.number, unit.column, [], unit.intent)
            ]
        if unit.kind == "pause":
            after = [p for p in frontier if self.vertices[p].kind == "pause"]
            if after:
                first = self.vertices[after[0]]
                raise line.error(
                    unit.column,
                    f"this pause can follow the pause of line {first.line} (the steps between "
                    "may be skipped); merge them or make a step between them required",
                )
            bounds = unit.bounds
            return [self.add("pause", None, bounds, line.number, unit.column, frontier)]
        made = [
            self.add(unit.kind, w, None, line.number, unit.column, frontier, unit.intent)
            for w in unit.words
            if w
        ]
        skip = unit.kind == "filler" or "" in unit.words
        return _union(made, frontier) if skip else made


def _union(*lists: list[str]) -> list[str]:
    return list(dict.fromkeys(v for lst in lists for v in lst))


def parse_script(
    source: str, path: str | Path = "<script>", legs: Sequence[str] | None = None
) -> Script:
    """Parse a script (see the module docstring).

    Args:
        source: The script's text.
        path: Its file, named in errors.
        legs: The exercise's leg names, in order, that ``@leg`` marks must name (None: any
            names, unchecked against an exercise).

    Raises:
        ScriptError: naming the file, line and column: unbalanced or nested brackets, an empty
            alternative, ``[]`` or filler, a bad ``(pause ...)`` or ``@pause``, an unknown
            ``@`` directive, a first step that is not a single phrase, two pauses that can
            follow each other, a script that can end with a pause, a script with no steps; a
            ``@leg`` mark inside a line, without one name, naming a leg twice, a leg ``legs``
            lacks or out of their order, and a step before the first mark of a script with
            marks; an ``<INTENT>`` not in :data:`~langenv.speech.intents.INTENTS`, empty, not
            right after a wording's words, a second one, or words after it.
    """
    path = Path(path)
    marks: dict[str, tuple[int, int]] = {}
    b = _Builder(path)
    settings: dict[str, object] = {
        "@pause": DEFAULT_PAUSE,
        "@voice": "stretch",
        "@final-wait": True,
    }
    frontier: list[str] = []
    repeats: list[ScriptRepeat] = []
    for number, raw in enumerate(source.splitlines(), start=1):
        text = raw.rstrip()
        if not text.strip() or text.lstrip().startswith("#"):
            continue
        line = _Line(path, number, text)
        _no_mark_inside(line, text)
        if text.split()[0] == _MARK:
            _mark(line, text, b, marks, legs)
            continue
        if text.lstrip().startswith("@"):
            _directive(line, text, bool(frontier), settings)
            continue
        rep = _REPEAT_AT_END.search(text)
        if rep is not None:
            line = _Line(path, number, text[: rep.start()].rstrip())
        outs: list[list[str]] = []
        alternatives = line.alternatives()
        if not b.vertices and len(alternatives) > 1:
            col, alt = alternatives[1]
            raise line.error(
                col + len(alt) - len(alt.lstrip()),
                "the speech starts with one wording: the first step must be a single phrase "
                "(no alternatives)",
            )
        for col, alt in alternatives:
            cur = frontier
            for unit in line.units(col, alt):
                cur = b.unit(line, unit, cur)
            outs.append(cur)
        new = _union(*outs)
        if rep is not None:
            repeats.append(_repeat(line, rep, text, [v for v in new if v not in frontier], b))
        frontier = new
    if not b.vertices:
        raise ScriptError(f"{path}: the script has no steps (one line per step of the exercise)")
    ends = [v for v in frontier if b.vertices[v].kind == "pause"]
    if ends:
        v = b.vertices[ends[0]]
        raise ScriptError(
            f"{path}:{v.line}:{v.column}: the speech can end with this pause; it must end with "
            "its last words (move the pause before a step, or make the last step required)"
        )
    pause = settings["@pause"]
    assert isinstance(pause, float)
    wait = settings["@final-wait"]
    assert isinstance(wait, bool)
    return Script(path, pause, b.vertices, str(settings["@voice"]), repeats, wait, marks)


_MARK = "@leg"
_MARK_RE = re.compile(r"@leg\b")


def _no_mark_inside(line: _Line, text: str) -> None:
    """Refuse a ``@leg`` mark that does not start its line."""
    start = len(text) - len(text.lstrip())
    for m in _MARK_RE.finditer(text):
        if m.start() != start:
            raise line.error(
                m.start() + 1,
                "a @leg mark stands on its own line, before the lines of its leg (e.g. "
                "'@leg out' above them)",
            )


def _mark(
    line: _Line,
    text: str,
    b: _Builder,
    marks: dict[str, tuple[int, int]],
    legs: Sequence[str] | None,
) -> None:
    """Apply one ``@leg NAME`` line: the lines after it are ``NAME``'s."""
    col = len(text) - len(text.lstrip()) + 1
    parts = text.split()
    if len(parts) != 2:
        raise line.error(col, f"@leg takes one leg name, e.g. '@leg out', got {text.strip()!r}")
    name = parts[1]
    at = text.index(name, col - 1 + len(_MARK)) + 1
    if name in marks:
        raise line.error(
            at, f"leg {name!r} is marked twice (first on line {marks[name][0]}); mark each leg once"
        )
    if legs is not None:
        _check_mark_order(line, at, name, marks, tuple(legs))
    if b.vertices and not marks:
        first = next(iter(b.vertices.values()))
        raise ScriptError(
            f"{line.path}:{first.line}:{first.column}: this step comes before the first @leg mark "
            f"(line {line.number}); in a script with marks every step follows one: put a mark "
            "above it (e.g. '@leg NAME' with the exercise's first leg)"
        )
    marks[name] = (line.number, at)
    b.leg = name


def _check_mark_order(
    line: _Line, at: int, name: str, marks: dict[str, tuple[int, int]], legs: tuple[str, ...]
) -> None:
    """Refuse a mark naming a leg the exercise lacks, or out of the exercise's order."""
    if name not in legs:
        raise line.error(at, f"{name!r} is not a leg of the exercise; its legs: {', '.join(legs)}")
    if marks:
        prev = next(reversed(marks))
        if legs.index(name) < legs.index(prev):
            raise line.error(
                at,
                f"leg {name!r} is marked after {prev!r}, which the exercise does later; marks "
                f"follow the exercise's order ({', '.join(legs)})",
            )


def _repeat(line: _Line, m: re.Match[str], text: str, made: list[str], b: _Builder) -> ScriptRepeat:
    """The ``(repeat N, gap MIN-MAX)`` that ends ``text``, over the line's new vertices."""
    col = m.start() + 1
    found = _REPEAT_RE.match(m.group(1))
    if found is None:
        raise line.error(
            col,
            f"'{m.group(0).strip()}' is not a repeat; write (repeat N) or (repeat N, gap MIN-MAX),"
            " e.g. (repeat 4, gap 1-3)",
        )
    times = int(found.group(1))
    if not 2 <= times <= MAX_REPEAT:
        raise line.error(col, f"a line repeats 2 to {MAX_REPEAT} times in a row, got {times}")
    gap = DEFAULT_GAP
    if found.group(2) is not None:
        lo = float(found.group(2))
        hi = float(found.group(3)) if found.group(3) is not None else lo
        if lo > hi or hi > MAX_PAUSE:
            raise line.error(col, f"bad gap {lo:g}-{hi:g}: it needs MIN <= MAX <= {MAX_PAUSE:g} s")
        gap = (lo, hi)
    last = [v for v in made if b.vertices[v].kind != "phrase"]
    if last or not made:
        raise line.error(
            col, "a repeated line must end with its words (no pause or filler after them)"
        )
    return ScriptRepeat(f"again_{line.number}", tuple(made), times, gap, line.number, col)


def _directive(line: _Line, text: str, started: bool, settings: dict[str, object]) -> None:
    """Apply one ``@`` line to ``settings``."""
    col = len(text) - len(text.lstrip()) + 1
    parts = text.split()
    if parts[0] not in settings:
        raise line.error(
            col,
            f"unknown directive {parts[0]!r}; known: @pause SECONDS, @voice stretch|natural, "
            "@final-wait on|off",
        )
    if started:
        raise line.error(col, f"{parts[0]} must come before the first step")
    if parts[0] == "@final-wait":
        if len(parts) != 2 or parts[1] not in ("on", "off"):
            raise line.error(col, f"@final-wait takes on or off, got {text.strip()!r}")
        settings["@final-wait"] = parts[1] == "on"
        return
    if parts[0] == "@voice":
        if len(parts) != 2 or parts[1] not in VOICES:
            raise line.error(col, f"@voice takes one of {', '.join(VOICES)}, got {text.strip()!r}")
        settings["@voice"] = parts[1]
        return
    settings["@pause"] = _pause_seconds(line, text, col, parts)


def _pause_seconds(line: _Line, text: str, col: int, parts: list[str]) -> float:
    try:
        value = float(parts[1]) if len(parts) == 2 else float("nan")
    except ValueError:
        value = float("nan")
    if not 0.0 <= value <= MAX_PAUSE:
        raise line.error(col, f"@pause takes seconds in [0, {MAX_PAUSE:g}], got {text.strip()!r}")
    return value


# ---------------------------------------------------------------------------------- writing
def _num(x: float) -> str:
    return f"{x:g}"


def _id(vid: str) -> str:
    """A vertex id as YAML reads it back: quoted when YAML would read it as something else
    (``yes``, ``no``, ``on``, ``off``, ``null``, a number)."""
    return vid if yaml.safe_load(vid) == vid else json.dumps(vid)


def _ids(vids: list[str] | tuple[str, ...]) -> str:
    return ", ".join(_id(v) for v in vids)


def graph_yaml(script: Script, source_name: str) -> str:
    """The phrase graph YAML (SPEC §4) of a parsed script, the same bytes for the same script."""
    out = [
        f"# Written by `langctrl speech author {source_name}` from its plain-text script:",
        "# edit the script and run the command again rather than editing this file.",
        f"start: {_id(script.start)}",
        f"pause: {_num(script.pause)}   # s of silence after each clip at a = 1",
    ]
    if script.voice != "stretch":
        out.append(f"voice: {script.voice}   # how the speech pace is voiced")
    out.append(
        f"final_wait: {'true' if script.final_wait else 'false'}"
        "   # the last phrase waits for the motion"
    )
    if script.marks:
        out.append(f"legs: [{_ids(script.legs)}]   # the exercise's legs the lines speak about")
    if script.repeats:
        out.append("repeats:   # lines the speech may say again while the motion lasts")
        for r in script.repeats:
            out.append(
                f"  {r.name}: {{phrases: [{_ids(r.phrases)}], times: {r.times}, "
                f"gap: [{_num(r.gap[0])}, {_num(r.gap[1])}]}}   # line {r.line}"
            )
    out += [
        "phrases:",
    ]
    for v in script.vertices.values():
        out.append(f"  {_id(v.id)}:   # line {v.line}")
        if v.leg is not None:
            out.append(f"    leg: {_id(v.leg)}")
        if v.kind == "pause":
            assert v.bounds is not None
            out.append(f"    pause: [{_num(v.bounds[0])}, {_num(v.bounds[1])}]")
        else:
            if v.kind == "filler":
                out.append("    filler: true")
            out.append(f"    text: {json.dumps(v.text, ensure_ascii=False)}")
            if v.intent is not None:
                out.append(f"    intent: {v.intent}")
        out.append(f"    next: [{_ids(v.next)}]")
    return "\n".join(out) + "\n"


def author(
    script_path: str | Path,
    out: str | Path,
    clips: ClipLibrary | None = None,
    legs: Sequence[str] | None = None,
) -> PhraseGraph:
    """Write the phrase graph of a script to ``out`` and return it, loaded and validated.

    ``legs``: the exercise's leg names that the script's ``@leg`` marks must name, in order
    (None: unchecked).

    The YAML is written to a temporary file beside ``out`` and loaded from there (every clip
    synthesised and timed, the TTS cache used); only a valid graph replaces ``out``.

    Raises:
        ScriptError: for a bad script (file, line, column) or a graph the script makes that is
            invalid (the vertex and the line it came from), e.g. a filler clip that is too long.
        PhraseGraphError: when the script cannot be read.
    """
    script_path, out = Path(script_path), Path(out)
    try:
        source = script_path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        reason = getattr(exc, "strerror", None) or exc
        raise PhraseGraphError(f"{script_path}: cannot read script: {reason}") from None
    script = parse_script(source, script_path, legs)
    text = graph_yaml(script, script_path.name)
    if not out.parent.is_dir():
        raise ScriptError(f"{out}: directory {out.parent} does not exist")
    fd, tmp_path = temp_file(out.parent, prefix=f".{out.stem}.", suffix=".yaml")
    tmp = str(tmp_path)
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as f:
            f.write(text)
        try:
            graph = PhraseGraph.load(tmp, clips)
        except PhraseGraphError as exc:
            raise ScriptError(_located(str(exc), script, tmp)) from None
        os.replace(tmp, out)
    finally:
        Path(tmp).unlink(missing_ok=True)
    graph.path = out
    return graph


def _located(message: str, script: Script, tmp: str) -> str:
    """A graph's error messages with the script's file, line and column of each vertex named."""
    lines = []
    for msg in message.splitlines():
        msg = msg.replace(f"{tmp}: ", "")
        reps = {r.name: f"{script.path}:{r.line}:{r.column}" for r in script.repeats}
        ids = [i for i in re.findall(r"'([^']+)'", msg) if i in script.vertices or i in reps]
        where = (
            (reps[ids[0]] if ids[0] in reps else script.where(ids[0])) if ids else str(script.path)
        )
        lines.append(f"{where}: {msg}")
    return "\n".join(lines)
