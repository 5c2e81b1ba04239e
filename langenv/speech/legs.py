"""Speech in step with every leg: a script's legs, the waits between them, and each leg's horizon.

A script may say which leg of the exercise each of its lines speaks about (``@leg NAME``); the
graph then records the leg of every vertex (the YAML's ``legs`` and each vertex's ``leg``). The
paper's law is applied at every leg instead of once for the whole motion:

* **Segments.** The legs that have words are the graph's *segments*, in order; segment ``j``
  speaks while the motion does the exercise's legs from its own up to the leg before the next
  segment's (a leg without words is spoken about by the segment before it; the first segment
  starts with the motion). An unmarked graph is one segment: the whole motion, as in the paper.
* **Plans stop at a segment's end.** ``t_min``/``t_max`` of a vertex, and so the choice rule's
  mids, count the speech from the vertex to the end of its segment's lines; the pause rule and the
  speech ETC plan to the same end.
* **The words of a leg wait for their leg.** Every way from one segment's words to the next
  goes through a *gate*: a silence (a pause vertex ``LEG#gate``, planned as 0 to ``WAIT_PLAN`` s,
  open above) that lasts until the motion enters the next segment's legs, as the last phrase
  waits for the motion's end (:mod:`langenv.speech.repeat`); words that run late reach it after
  the leg has begun, and it then ends with the tick (the step) it begins in, so that the leg's
  first words are the policy's next choice, not the rule's. A pause whose children all begin
  the next segment is itself opened into the gate; a pause written at the start of a leg's lines
  is the silence before them and belongs to the leg before. (Ending the gate early by half a
  filler, so that "Okay," falls before the leg, was measured worse: the fillers' lead is in
  nominal seconds, which a resisting person stretches.)
* **Horizons.** The motion's time to the end of segment ``j`` is :meth:`LegPlan.horizons`' ``j``-th
  value (the last segment's is the whole motion's ETC ``t_x``); the law aligns the speech's time to
  the end of the *horizon* segment ``H`` (the later of the motion's segment and the speech's) with
  the motion's time to it; a choice compares each child's mid with the motion's time to the end of
  the child's segment.

Nothing changes for an unmarked graph: one segment, no gate, horizon ``t_x``, the same operations
in the same order.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from langenv.errors import ConfigError
from langenv.speech.repeat import SEP, WAIT_PLAN

__all__ = [
    "GATE",
    "LegPlan",
    "add_gates",
    "leg_plan",
    "leg_problems",
    "segment_of",
    "unrolled_legs",
]

GATE = "gate"
"""Suffix of a gate's id (``back#gate``: the silence before the words of leg ``back``)."""


def leg_problems(
    label: str, phrases: Mapping[str, Any], legs: Sequence[str], leg_of: Mapping[str, str]
) -> list[str]:
    """What is wrong with a graph's legs, one line each (naming the file and the vertex): a
    leg named twice or not a name, a vertex without a leg (or with one in an unmarked graph), a
    leg that is not listed, an edge back to an earlier leg, an edge that passes by a leg with
    words (a leg's lines must not all be skippable)."""
    if not legs:
        extra = sorted(set(leg_of))
        return (
            [f"{label}: vertices {extra} have a 'leg' but the graph lists no 'legs'"]
            if extra
            else []
        )
    problems: list[str] = []
    if len(set(legs)) != len(legs) or not all(isinstance(x, str) and x for x in legs):
        problems.append(f"{label}: 'legs' must be distinct leg names, got {list(legs)!r}")
        return problems
    rank = {name: i for i, name in enumerate(legs)}
    for pid, ph in phrases.items():
        leg = leg_of.get(pid)
        if leg is None:
            problems.append(f"{label}: {ph.kind} {pid!r}: no 'leg' (every vertex of a graph "
                            "with 'legs' names its leg)")  # fmt: skip
        elif leg not in rank:
            problems.append(f"{label}: {ph.kind} {pid!r}: leg {leg!r} is not one of {list(legs)}")
    if problems:
        return problems
    spoken = sorted({rank[leg_of[p]] for p in phrases if not phrases[p].is_pause})
    for pid, ph in phrases.items():
        for v in ph.next:
            a, b = rank[leg_of[pid]], rank[leg_of[v]]
            if b < a:
                problems.append(
                    f"{label}: {ph.kind} {pid!r} (leg {legs[a]!r}) leads back to {v!r} "
                    f"(leg {legs[b]!r}): legs follow one another in order"
                )
            skipped = [legs[k] for k in spoken if a < k < b]
            if skipped:
                problems.append(
                    f"{label}: {ph.kind} {pid!r} (leg {legs[a]!r}) leads to {v!r} (leg "
                    f"{legs[b]!r}), passing by the words of leg {skipped[0]!r}: a leg needs a "
                    "line that is always said"
                )
    return problems


def unrolled_legs(
    table: Mapping[str, Any], leg_of: Mapping[str, str], repeat_legs: Mapping[str, str]
) -> dict[str, str]:
    """The leg of every unrolled vertex: a vertex the graph's own id names (``P``, ``P#3``,
    ``T#wait``, ``F#end``) has its leg, a repeat's gap (``NAME#gapK``) its repeat's."""
    out: dict[str, str] = {}
    for u in table:
        base = u.split(SEP, 1)[0]
        out[u] = leg_of[base] if base in leg_of else repeat_legs[base]
    return out


def segment_of(table: Mapping[str, Any], legs: Sequence[str], leg: Mapping[str, str],
               order: Sequence[str]) -> dict[str, int]:  # fmt: skip
    """Each vertex's segment (the rank of its leg among the legs with words); a pause whose
    parents are all in earlier segments belongs to the latest of them (the silence before a
    leg's words is the end of the leg before)."""
    worded = [name for name in legs if any(leg[u] == name for u in table if not table[u].is_pause)]
    rank = {name: i for i, name in enumerate(worded)}
    seg: dict[str, int] = {}
    for u in table:
        name = leg[u]
        # a pause in a leg without words: the segment before (its words' silence)
        seg[u] = (
            rank[name]
            if name in rank
            else max((rank[n] for n in worded if legs.index(n) < legs.index(name)), default=0)
        )
    parents: dict[str, list[str]] = {u: [] for u in table}
    for u in order:
        for v in table[u].next:
            parents[v].append(u)
    for u in order:  # parents first
        if table[u].is_pause and parents[u]:
            before = max(seg[p] for p in parents[u])
            if before < seg[u]:
                seg[u] = before
    return seg


def add_gates(
    table: dict[str, Any], seg: dict[str, int], names: Sequence[str], make: Any
) -> tuple[set[str], set[str]]:
    """The gates between segments, in place (module docstring): returns ``(gates, opened)``,
    the vertices whose children begin the next segment and the pauses opened above their
    bounds (the new gates and the pauses that became gates)."""
    gates: set[str] = set()
    opened: set[str] = set()
    for t in range(1, len(names)):
        entries = {v for v in table if seg[v] == t and any(
            seg[u] < t and v in table[u].next for u in table)}  # fmt: skip
        parents = [u for u in table if seg[u] < t and set(table[u].next) & entries]
        last = {u for u in parents if table[u].is_pause and set(table[u].next) <= entries}
        gates |= last
        opened |= last
        redirect = [u for u in parents if u not in last]
        if not redirect:
            continue
        gate = f"{names[t]}{SEP}{GATE}"
        kids: list[str] = []
        for u in redirect:
            ph = table[u]
            kids += [v for v in ph.next if v in entries and v not in kids]
            new = tuple(dict.fromkeys(gate if v in entries else v for v in ph.next))
            table[u] = make(u, ph.text, ph.audio, new, ph.kind, ph.bounds)
        table[gate] = make(gate, None, None, tuple(kids), "pause", (0.0, WAIT_PLAN))
        seg[gate] = t - 1
        gates.add(gate)
        opened.add(gate)
    return gates, opened


@dataclass(frozen=True)
class LegPlan:
    """A marked graph's segments on an exercise's legs: the motion's time to each segment's end.

    Attributes:
        last_leg: Per segment, the index of the exercise's last leg it speaks during (the last
            segment's is the exercise's last leg).
        rest: Per segment, the motion's nominal time from the end of that leg to the end of the
            exercise (s; FastETC's rest after the switch at the guided plateau speed); 0 for the
            last segment.
    """

    last_leg: tuple[int, ...]
    rest: tuple[float, ...]

    def __post_init__(self) -> None:
        n = len(self.last_leg)
        if n == 0 or len(self.rest) != n:
            raise ConfigError(f"LegPlan: one last leg and one rest per segment, got {self!r}")
        if any(b <= a for a, b in zip(self.last_leg, self.last_leg[1:], strict=False)):
            raise ConfigError(f"LegPlan: segments' last legs must increase, got {self.last_leg}")
        if not all(math.isfinite(r) and r >= 0.0 for r in self.rest):
            raise ConfigError(f"LegPlan: rests must be finite and >= 0, got {self.rest}")

    @classmethod
    def whole(cls, n_legs: int) -> LegPlan:
        """One segment: the whole motion (an unmarked graph)."""
        return cls((max(0, n_legs - 1),), (0.0,))

    @property
    def segments(self) -> int:
        """Number of segments."""
        return len(self.last_leg)

    def motion_segment(self, leg: int) -> int:
        """The segment the motion is in while it guides leg ``leg`` (the last once done)."""
        for j, last in enumerate(self.last_leg):
            if leg <= last:
                return j
        return len(self.last_leg) - 1

    def horizon(self, j: int, t_x: float, t_leg: float, leg: int) -> float:
        """The motion's time to the end of segment ``j`` (s; mirrored by
        :func:`langenv.speech.legs_kernels.horizon`): ``t_x`` for the last segment, 0 once the
        motion is past it, the time to the current leg's switch ``t_leg`` when it ends there,
        else ``t_x`` less the nominal rest after it (at least ``t_leg``)."""
        if j == len(self.last_leg) - 1:
            return t_x
        last = self.last_leg[j]
        if leg > last:
            return 0.0
        if leg == last:
            return t_leg
        rest = t_x - self.rest[j]
        return rest if rest > t_leg else t_leg

    def horizons(self, t_x: float, t_leg: float, leg: int) -> tuple[float, ...]:
        """:meth:`horizon` of every segment."""
        return tuple(self.horizon(j, t_x, t_leg, leg) for j in range(len(self.last_leg)))

    def packed(self, seg: Sequence[int], gate: Sequence[bool]) -> np.ndarray:
        """The plan and each vertex's segment and gate flag (in the compiled graph's order) as
        :mod:`langenv.speech.legs_kernels` reads them: ``[S, n, last_leg (S), rest (S), seg (n),
        gate (n)]``."""
        s, n = len(self.last_leg), len(seg)
        return np.array(
            [s, n, *self.last_leg, *self.rest, *seg, *(1.0 if g else 0.0 for g in gate)],
            dtype=np.float64,
        )


def leg_plan(
    graph: Any, leg_names: Sequence[str], rest: Callable[[int], float], exercise: str = ""
) -> LegPlan:
    """The plan of ``graph``'s segments on an exercise whose legs are ``leg_names`` (``rest(k)``:
    the motion's nominal time after leg ``k``'s switch, :meth:`FastETC.nominal_rest
    <langenv.control.motion_etc.FastETC.nominal_rest>`).

    Raises:
        ConfigError: naming the graph's file and the exercise, for a leg the exercise does not
            have or legs out of the exercise's order.
    """
    names = graph.segment_names
    if not names:
        return LegPlan.whole(len(leg_names))
    index = {name: i for i, name in enumerate(leg_names)}
    where = f"{graph.path or '<phrase graph>'}"
    what = f"exercise {exercise!r}" if exercise else "the exercise"
    unknown = [n for n in graph.legs if n not in index]
    if unknown:
        raise ConfigError(
            f"{where}: leg {unknown[0]!r} is not a leg of {what} (its legs: "
            f"{', '.join(leg_names)}): speak a script marked with the exercise's legs (its "
            "script.graph; `langctrl speech author SCRIPT --exercise EXERCISE` writes one) or "
            "an unmarked graph (`study`)"
        )
    starts = [index[n] for n in names]
    if any(b <= a for a, b in itertools.pairwise(starts)):
        raise ConfigError(
            f"{where}: the script's legs {list(graph.legs)} are not in the order of {what}'s "
            f"({', '.join(leg_names)})"
        )
    last = [b - 1 for b in starts[1:]] + [len(leg_names) - 1]
    return LegPlan(tuple(last), (*tuple(rest(k) for k in last[:-1]), 0.0))
