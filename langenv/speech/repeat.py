"""Speech that never runs out: repeatable phrases and the last phrase that waits for the motion.

A phrase graph (:mod:`langenv.speech.graph`) stays a DAG for the paper's choice rule. Two things a
therapist does with a slow patient are written on top of it and *unrolled* into plain vertices
when the graph is built, so that ``t_min``/``t_max``, the choice rule, the ETCs, the compiled
path, the live stream and the robot loop all work on an ordinary finite DAG:

**Repeats.** A *repeat* names a group of phrases (the alternatives of one step, e.g. "Keep going."
| "Nice and slow.") that may be said again while the motion lasts: after any of them, and a
silence (the *gap*, a pause of ``gap = [min, max]`` s at a = 1, on top of the graph's ``pause``
after every clip), any of them may be said again, at most ``times`` sayings of the group in a
row. Unrolled, saying ``k`` of phrase ``P`` is the vertex ``P#k`` (``P`` itself for ``k = 1``)
whose children are ``P``'s own followers, then (for ``k < times``) the gap pause ``NAME#gapk``,
whose children are every member's ``#k+1``. So ``t_max`` grows with ``times`` and the choice
rule takes another round exactly when the motion's time to go is nearer the longer speech.

**The last phrase waits for the motion** (the graph's ``final_wait``, on for the product's graphs,
off for the study's). Every final phrase ``T`` is preceded by an open silence: the pause vertex
``T#wait`` between each parent and ``T``, except a pause that leads only to the end, whose own
maximum is opened up instead (a pause that may also lead to other words keeps its bounds and is
followed by ``T#wait``). A filler that leads only to the end (``{okay|so} And you're done.``) is
said after the silence, with its phrase: the wait ``F#wait`` goes before the filler ``F``.
Its length is planned like any pause's (:meth:`PhraseGraph.pause_length
<langenv.speech.graph.PhraseGraph.pause_length>`: what makes the speech end at the motion's
end) and replanned at every step while it lasts, without the pause's upper bound (at most
:data:`WAIT_MAX`): the last phrase starts when the motion's time to go is its length. For the
choice rule it counts as its *planned* bounds (0 to :data:`WAIT_PLAN` for ``T#wait``, as written
for a pause), so the choices, ``t_min``/``t_max`` and the rule's mids are those of the words and
a short planned silence: only the silence before the last phrase stretches beyond that. A
script needs no line for it.

**The motion goes back after the last phrase** (graphs whose last phrase waits). A person may
push the hand back once the last words have begun ("And you're done." said, then seconds of
motion again). When the motion is still going :data:`REOPEN_AFTER` s after the speech ended,
and its time to go can hold the shortest words from there to the end, the speech goes on from
:func:`reopen_vertex` (the shortest first saying of a repeat that leads to the last phrase's
wait: "Keep going.", then, by the same rules, more sayings or the wait and the last phrase
again; a script without such a line: the wait and the last phrase again), at most
:data:`MAX_REOPENS` times a session. A session whose motion ends within
:data:`REOPEN_AFTER` s of its speech is not touched.

A plan says a repeat once: ``t_min``/``t_max`` of a vertex (and so the choice rule's mids) leave
out its gap children, so a repeat whose ``times`` is large does not make every earlier wording
look short; another saying is chosen, at each saying's end, when the motion's time to go is
nearer one more saying than the end.

Both keep the paper's choice rule: nothing here looks at the paces.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from langenv.errors import PhraseGraphError

__all__ = [
    "DEFAULT_GAP",
    "MAX_REOPENS",
    "MAX_REPEAT",
    "REOPEN_AFTER",
    "SEP",
    "WAIT_MAX",
    "WAIT_PLAN",
    "Repeat",
    "expand",
    "is_gap",
    "parse_repeats",
    "reopen_time",
    "reopen_vertex",
    "repeat_problems",
]

MAX_REPEAT = 20
"""The most sayings a repeat may have in a row (a bound keeps the graph finite)."""
DEFAULT_GAP = (1.0, 3.0)
"""Silence between two sayings of a repeat when a file gives no ``gap`` (s at a = 1, on top of
the graph's ``pause``)."""
WAIT_MAX = 3600.0
"""Longest silence before the last phrase (s at a = 1): the wait is open-ended in practice."""
WAIT_PLAN = 1.5
"""How long a plan counts the wait before the last phrase, at most (s at a = 1): the choice rule
aims the words about half of it before the motion's end. Overshooting costs more
than stopping short: a wait fills a short speech, while the paper's law slows the voice, never
speeds it, when the person resists as the motion ends."""
REOPEN_AFTER = 1.0
"""Seconds of motion after the speech's end before the speech goes on (the module docstring):
the bar of ``|AM|``, so that a session the bar passes is never changed."""
MAX_REOPENS = 3
"""The most times a session's speech goes on after its end."""
SEP = "#"
"""Separator of the ids of unrolled vertices (``keep_going#2``, ``encourage#gap1``,
``done#wait``); a graph file's own ids may not contain it."""
_MAX_GAP = 10.0
_KEYS = frozenset({"phrases", "times", "gap"})


@dataclass(frozen=True)
class Repeat:
    """A group of phrases that may be said again, at most ``times`` sayings in a row.

    Attributes:
        name: The repeat's name (ids of its gap pauses: ``NAME#gapK``).
        phrases: The phrases of the group (the alternatives of one step), in order.
        times: Most sayings of the group in a row, ``2 <= times <= MAX_REPEAT``.
        gap: Silence between two sayings, ``(min, max)`` s at a = 1, ``0 <= min <= max <= 10``
            (on top of the graph's ``pause`` after every clip).
    """

    name: str
    phrases: tuple[str, ...]
    times: int
    gap: tuple[float, float] = DEFAULT_GAP

    def __post_init__(self) -> None:
        where = f"repeat {self.name!r}"
        if not isinstance(self.name, str) or not self.name or SEP in self.name:
            raise PhraseGraphError(
                f"repeat name must be a non-empty str without {SEP!r}, got {self.name!r}"
            )
        phrases = (self.phrases,) if isinstance(self.phrases, str) else tuple(self.phrases)
        if not phrases or not all(isinstance(p, str) and p for p in phrases):
            raise PhraseGraphError(f"{where}: 'phrases' must be a non-empty list of phrase ids")
        if len(set(phrases)) != len(phrases):
            raise PhraseGraphError(f"{where}: 'phrases' lists a phrase twice")
        object.__setattr__(self, "phrases", phrases)
        problem = _times_problem(self.times) or _gap_problem(self.gap)
        if problem:
            raise PhraseGraphError(f"{where}: {problem}")
        lo, hi = self.gap
        object.__setattr__(self, "gap", (float(lo), float(hi)))


def _times_problem(times: object) -> str:
    if times is None:
        return (
            f"a repeat needs a bound: 'times', the most sayings in a row (2-{MAX_REPEAT}); "
            "a repeat without one would never let the graph end"
        )
    if isinstance(times, bool) or not isinstance(times, int) or not 2 <= times <= MAX_REPEAT:
        return (
            f"'times' must be an integer from 2 to {MAX_REPEAT} (sayings in a row), got {times!r}"
        )
    return ""


def _gap_problem(gap: object) -> str:
    if not isinstance(gap, list | tuple) or len(gap) != 2:
        return f"'gap' must be seconds of silence, a number or [min, max], got {gap!r}"
    lo, hi = gap
    ok = all(
        isinstance(x, int | float) and not isinstance(x, bool) and math.isfinite(x) for x in gap
    )
    if not ok:
        return f"'gap' bounds must be numbers of seconds, got {list(gap)!r}"
    if lo < 0.0 or lo > hi or hi > _MAX_GAP:
        return f"bad gap [{lo}, {hi}]: it needs 0 <= min <= max <= {_MAX_GAP:g} s"
    return ""


def parse_repeats(path: object, raw: object) -> tuple[dict[str, Repeat], list[str]]:
    """The ``repeats`` mapping of a graph file (``NAME: {phrases, times, gap}``) and the problems
    found in it, each naming the file and the repeat."""
    if raw is None:
        return {}, []
    if not isinstance(raw, dict):
        return {}, [f"{path}: 'repeats' must be a mapping of name -> {{phrases, times, gap}}"]
    out: dict[str, Repeat] = {}
    problems: list[str] = []
    for name, spec in raw.items():
        where = f"{path}: repeat {name!r}"
        if not isinstance(spec, dict):
            problems.append(f"{where}: must be a mapping with 'phrases', 'times' and 'gap'")
            continue
        bad = sorted(str(k) for k in spec if k not in _KEYS)
        if bad:
            problems.append(f"{where}: unknown key(s) {bad}; allowed: {sorted(_KEYS)}")
            continue
        gap: Any = spec.get("gap", DEFAULT_GAP)
        if isinstance(gap, int | float) and not isinstance(gap, bool):
            gap = (gap, gap)
        try:
            times: Any = spec.get("times")
            out[str(name)] = Repeat(str(name), spec.get("phrases") or (), times, gap)
        except PhraseGraphError as exc:
            problems.append(f"{path}: {exc}")
    return out, problems


def repeat_problems(
    label: str, phrases: Mapping[str, Any], repeats: Mapping[str, Repeat]
) -> list[str]:
    """What makes ``repeats`` impossible on these (source) vertices, one line each: an unknown
    phrase, a pause or filler, a phrase in two repeats, a final phrase, members that follow one
    another (directly or through other vertices), or a repeat that can never be left."""
    problems: list[str] = []
    owner: dict[str, str] = {}
    for rep in repeats.values():
        where = f"{label}: repeat {rep.name!r}"
        members = set(rep.phrases)
        for pid in rep.phrases:
            ph = phrases.get(pid)
            if ph is None:
                problems.append(f"{where}: {pid!r} is not a phrase of this graph")
                continue
            if ph.kind != "phrase":
                problems.append(f"{where}: {ph.kind} {pid!r} cannot repeat (only phrases can)")
            if pid in owner:
                problems.append(f"{where}: phrase {pid!r} is also in repeat {owner[pid]!r}")
            owner[pid] = rep.name
            if not ph.next:
                problems.append(
                    f"{where}: phrase {pid!r} ends the speech and cannot repeat (the last phrase "
                    "is said once, as the motion ends)"
                )
                continue
            inside = [v for v in ph.next if v in members]
            if inside:
                problems.append(
                    f"{where}: phrase {pid!r} lists {inside[0]!r} of the same repeat in its next; "
                    "the repeat itself says which may follow which"
                )
            if all(v in members for v in ph.next):
                problems.append(
                    f"{where}: can never be left: after its last saying phrase {pid!r} has "
                    "nowhere to go (give it a next outside the repeat)"
                )
            elif not inside:
                later = _first_reached(phrases, ph.next, members)
                if later is not None:
                    problems.append(
                        f"{where}: phrase {pid!r} leads to {later!r} of the same repeat; another "
                        "saying after it would go round for ever (the members of a repeat are "
                        "alternatives of one step)"
                    )
        for pid in rep.phrases:
            if SEP in pid:
                problems.append(f"{where}: phrase id {pid!r} contains {SEP!r}")
    return problems


def _first_reached(
    phrases: Mapping[str, Any], start: tuple[str, ...], targets: set[str]
) -> str | None:
    """A vertex of ``targets`` that some path from ``start`` reaches (``start`` included)."""
    seen: set[str] = set()
    stack = list(start)
    while stack:
        u = stack.pop()
        if u in targets:
            return u
        if u in seen or u not in phrases:
            continue
        seen.add(u)
        stack.extend(phrases[u].next)
    return None


def expand(
    phrases: Mapping[str, Any],
    duration: Mapping[str, float],
    repeats: Mapping[str, Repeat],
    final_wait: bool,
    make: Any,
) -> tuple[dict[str, Any], dict[str, float], frozenset[str]]:
    """The unrolled vertices (module docstring).

    Args:
        phrases: The graph's own (validated) vertices by id.
        duration: Clip lengths of its phrases and fillers (s).
        repeats: Its repeats (validated against ``phrases``).
        final_wait: Whether the last phrase waits for the motion.
        make: The vertex constructor (``Phrase``: id, text, audio, next, kind, bounds).

    Returns:
        ``(vertices, durations, open)``: the unrolled vertices by id in a stable order, the clip
        length of each phrase and filler, and the pauses whose length is open above their
        bounds (the waits before the last phrase).
    """
    nxt = {u: list(ph.next) for u, ph in phrases.items()}
    dur = {u: float(d) for u, d in duration.items()}
    extra: dict[str, Any] = {}
    for rep in repeats.values():
        for k in range(1, rep.times + 1):
            gap = f"{rep.name}{SEP}gap{k}"
            for m in rep.phrases:
                src = phrases[m]
                kids = [*src.next, gap] if k < rep.times else list(src.next)
                if k == 1:
                    nxt[m] = kids
                else:
                    here = f"{m}{SEP}{k}"
                    extra[here] = make(here, src.text, src.audio, tuple(kids), src.kind, None)
                    dur[here] = dur[m]
            if k < rep.times:
                again = tuple(f"{m}{SEP}{k + 1}" for m in rep.phrases)
                extra[gap] = make(gap, None, None, again, "pause", rep.gap)
    table = {
        u: make(u, ph.text, ph.audio, tuple(nxt[u]), ph.kind, ph.bounds)
        for u, ph in phrases.items()
    }
    table.update(extra)
    opened = _add_waits(table, dur, make) if final_wait else set()
    return table, {u: d for u, d in dur.items() if u in table}, frozenset(opened)


def reopen_time(graph: Any, t_end: float | None, reopens: int) -> float:
    """From when a session's speech that ended at ``t_end`` (s; None: it goes on) may go on
    after ``reopens`` times already (module docstring); ``inf``: not now."""
    if t_end is None or graph.reopen is None or reopens >= MAX_REOPENS:
        return math.inf
    return t_end + REOPEN_AFTER


def reopen_vertex(graph: Any) -> str | None:
    """Where the speech goes on after its end (module docstring) in ``graph`` (a
    :class:`~langenv.speech.graph.PhraseGraph`): among the first sayings of a repeat that lead
    to a last phrase's wait, the shortest (the first in the graph's order on a tie); without
    one, that wait itself (the last phrase said again, timed to end with the motion; a wait
    straight before a last phrase rather than one before its filler); None when the last
    phrase does not wait (the speech then ends as before)."""
    if not graph.final_wait:
        return None
    # the silences before a last phrase: the waits added, or a pause line opened into one
    waits = [u for u in graph.order if u in graph.opened and not graph.is_gate(u)]
    opened = set(waits)
    found = [
        u
        for u in graph.order
        if SEP not in u
        and u not in graph.pauses
        and opened.intersection(graph.children(u))
        and any(is_gap(k) for k in graph.children(u))
    ]
    if found:
        return min(found, key=lambda u: graph.duration[u])
    plain = [w for w in waits if any(graph.is_terminal(k) for k in graph.children(w))]
    return (plain or waits or [None])[0]  # a wait straight before a last phrase, not a filler


def is_gap(vertex: str) -> bool:
    """Whether ``vertex`` is a repeat's gap (``NAME#gapK``)."""
    head, sep, tail = vertex.rpartition(SEP)
    return bool(sep) and bool(head) and tail.startswith("gap") and tail[3:].isdigit()


def _add_waits(table: dict[str, Any], dur: dict[str, float], make: Any) -> set[str]:
    """Open silences before every final phrase (in place); returns the opened pauses.

    The silence goes before the words that end the speech: a final phrase, or a filler that
    leads only to them (``{okay|so} And you're done.`` is said as one piece after the wait, not
    "Okay", a silence, "And you're done."). A filler that leads both to the end and to other
    words is split (:func:`_split_fillers`), so that on its way to the end it too is said after
    the wait. A pause all of whose children end the speech is opened itself; a pause that may
    also lead elsewhere keeps its bounds (its silence is not the last one on those other ways)
    and is followed by the wait on its way to the end."""
    ending = _ending_words(table)
    while _split_fillers(table, dur, ending, make):
        ending = _ending_words(table)
    last_pauses = {u for u, ph in table.items() if ph.is_pause and set(ph.next) <= ending}
    opened: set[str] = set(last_pauses)
    for t in [u for u in table if u in ending]:
        wait = f"{t}{SEP}wait"
        parents = [u for u, ph in table.items() if t in ph.next]
        redirect = [u for u in parents if u not in ending and u not in last_pauses]
        if not redirect:
            continue
        for u in redirect:
            ph = table[u]
            kids = tuple(wait if v == t else v for v in ph.next)
            table[u] = make(u, ph.text, ph.audio, kids, ph.kind, ph.bounds)
        table[wait] = make(wait, None, None, (t,), "pause", (0.0, WAIT_PLAN))
        opened.add(wait)
    return opened


def _ending_words(table: dict[str, Any]) -> set[str]:
    """The words that end the speech: final phrases and the fillers that lead only to them
    (chains of fillers included)."""
    ending = {u for u, ph in table.items() if not ph.next and not ph.is_pause}
    grew = True
    while grew:
        more = {
            u
            for u, ph in table.items()
            if ph.kind == "filler" and ph.next and u not in ending and set(ph.next) <= ending
        }
        ending |= more
        grew = bool(more)
    return ending


def _split_fillers(
    table: dict[str, Any], dur: dict[str, float], ending: set[str], make: Any
) -> bool:
    """Split each filler ``F`` that leads both to ending words and to others (``{okay|so}
    [Almost there.]`` before the last phrase) into ``F`` (to the others) and ``F#end`` (the
    same words, to the ending ones), a sibling of ``F`` at each of its parents (in place);
    returns whether one was split."""
    split = False
    for f in [u for u, ph in table.items() if ph.kind == "filler" and u not in ending]:
        ph = table[f]
        ends = tuple(v for v in ph.next if v in ending)
        if not ends:
            continue
        twin = f"{f}{SEP}end"
        table[f] = make(f, ph.text, ph.audio, tuple(v for v in ph.next if v not in ending),
                        ph.kind, ph.bounds)  # fmt: skip
        table[twin] = make(twin, ph.text, ph.audio, ends, ph.kind, ph.bounds)
        dur[twin] = dur[f]
        for u, parent in list(table.items()):
            if f in parent.next and u != twin:
                kids = tuple(w for v in parent.next for w in ((v, twin) if v == f else (v,)))
                table[u] = make(u, parent.text, parent.audio, kids, parent.kind, parent.bounds)
        split = True
    return split
