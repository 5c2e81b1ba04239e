"""What makes a phrase graph valid: every check :class:`~langenv.speech.graph.PhraseGraph` runs
where it is built, one message per problem, each naming the graph (its file) and the vertex."""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass

from langenv.errors import PhraseGraphError
from langenv.speech.intents import intent_problem
from langenv.speech.legs import leg_problems
from langenv.speech.phrase import MAX_FILLER, MAX_PAUSE, Phrase, is_number
from langenv.speech.repeat import SEP, Repeat, repeat_problems
from langenv.speech.voice import VOICES

__all__ = [
    "GraphParts",
    "a_cycle",
    "duration_problems",
    "graph_problems",
    "intent_problems",
    "pause_problems",
    "strongly_connected",
    "structure_problems",
    "topological_order",
    "unreachable_problems",
    "vertex_table",
]


def vertex_table(
    label: str, phrases: Mapping[str, Phrase] | Iterable[Phrase]
) -> tuple[dict[str, Phrase], list[str]]:
    """The vertices by id, and the problems: not a :class:`Phrase`, an id twice, a key that is
    not its vertex's id.

    Raises:
        PhraseGraphError: an item that is not a :class:`Phrase`.
    """
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
                problems.append(f"{label}: phrase {key!r}: stored under a different id {ph.id!r}")
    return table, problems


def graph_problems(
    label: str,
    table: Mapping[str, Phrase],
    start: str,
    duration: Mapping[str, float],
    parts: GraphParts,
    found: Iterable[str] = (),
) -> list[str]:
    """Every problem of a graph: those ``found`` already (:func:`vertex_table`), then ``pause``
    and ``voice``, the structure (:func:`structure_problems`), each clip's duration, the
    repeats, ``final_wait``, the legs and the intents, in that order."""
    problems = list(found)
    if not is_number(parts.pause) or not 0.0 <= float(parts.pause) <= MAX_PAUSE:  # type: ignore[arg-type]
        problems.append(
            f"{label}: pause must be a number in [0, {MAX_PAUSE}] s, got {parts.pause!r}"
        )
    if parts.voice not in VOICES:
        problems.append(f"{label}: voice must be one of {list(VOICES)}, got {parts.voice!r}")
    problems += structure_problems(label, table, start)
    if not problems:
        problems += duration_problems(label, table, duration)
    reps = parts.repeats
    if not all(isinstance(r, Repeat) for r in reps.values()):
        problems.append(f"{label}: repeats must be Repeat objects, got {dict(reps)!r}")
    elif not problems:
        problems += [
            f"{label}: {ph.kind} {pid!r}: ids may not contain {SEP!r} (LangCtrl names the "
            "vertices it adds with it)"
            for pid, ph in table.items()
            if SEP in pid
        ]
        problems += repeat_problems(label, table, reps)
    if not isinstance(parts.final_wait, bool):
        problems.append(f"{label}: final_wait must be true or false, got {parts.final_wait!r}")
    if not problems:
        problems += leg_problems(label, table, parts.legs, parts.leg_of)
    problems += intent_problems(label, table, parts.intents)
    return problems


@dataclass(frozen=True)
class GraphParts:
    """What a graph holds besides its vertices and clips, as given (checked by
    :func:`graph_problems`, not here: every problem is reported at once)."""

    pause: object
    voice: object
    repeats: Mapping[str, Repeat]
    final_wait: object
    legs: tuple[str, ...]
    leg_of: Mapping[str, str]
    intents: Mapping[str, str]


def duration_problems(
    label: str, table: Mapping[str, Phrase], duration: Mapping[str, float]
) -> list[str]:
    """A clip without a duration, a duration that is not > 0 s, a filler longer than
    :data:`~langenv.speech.phrase.MAX_FILLER`."""
    problems: list[str] = []
    for pid, ph in table.items():
        if ph.is_pause:
            continue
        d = duration.get(pid)
        if d is None:
            problems.append(f"{label}: {ph.kind} {pid!r}: no duration")
        elif not is_number(d) or not 0.0 < float(d) < math.inf:
            problems.append(f"{label}: {ph.kind} {pid!r}: duration must be > 0 s, got {d!r}")
        elif ph.kind == "filler" and float(d) > MAX_FILLER:
            problems.append(
                f"{label}: filler {pid!r}: its clip lasts {float(d):.2f} s; a filler is "
                f"at most {MAX_FILLER} s (make it a phrase)"
            )
    return problems


def intent_problems(
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


def structure_problems(label: str, phrases: Mapping[str, Phrase], start: object) -> list[str]:
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
    for comp in strongly_connected({pid: ph.next for pid, ph in phrases.items()}):
        if len(comp) > 1 or comp[0] in phrases[comp[0]].next:
            cycle = a_cycle(phrases, set(comp))
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
    problems += pause_problems(label, phrases, start)
    return problems


def unreachable_problems(label: str, phrases: Mapping[str, Phrase], start: str) -> list[str]:
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


def pause_problems(label: str, phrases: Mapping[str, Phrase], start: str) -> list[str]:
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


def strongly_connected(successors: Mapping[str, Sequence[str]]) -> list[list[str]]:
    """The strongly connected components of the graph ``successors`` (each node -> the nodes it
    leads to, every one a key): Tarjan's algorithm, iterative (graphs can be deep)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    on_stack: set[str] = set()
    stack: list[str] = []
    comps: list[list[str]] = []
    counter = 0
    for root in successors:
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
            kids = successors[v]
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


def a_cycle(phrases: Mapping[str, Phrase], comp: set[str]) -> list[str]:
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


def topological_order(phrases: Mapping[str, Phrase]) -> tuple[str, ...]:
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
