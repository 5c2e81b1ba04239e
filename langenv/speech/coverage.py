"""Coverage of a phrase graph: the motion durations its speech can end together with.

A path of the graph lasts between ``lo`` and ``hi`` seconds at audio pace 1 (its pauses at their
bounds; without pauses ``lo == hi``). Played at a constant pace ``a`` it lasts ``lo/a .. hi/a``.
Over every path and every pace in ``[a_lo, a_hi]`` the graph's speech can last any time in a
union of intervals: that union is the graph's *coverage* at those paces. Two ranges matter:

* ``|a - 1| <= 0.1``: the motion durations the speech can match while the voice stays natural;
* ``a_min .. a_max`` (the env's pace limits, 0.6-1.4): what the aligner can reach at all.

The union is computed exactly by dynamic programming over the DAG (reverse topological order,
one merged interval set per vertex), not by listing paths, so it is cheap for any graph. It is the
coverage of the *words*: each pause at its planned bounds (:meth:`PhraseGraph.plan_range
<langenv.speech.graph.PhraseGraph.plan_range>`), repeats at most their ``times``. A graph whose
last phrase waits for the motion (``final_wait``) also ends together with any longer motion, with
silence before its last phrase for the difference.
"""

from __future__ import annotations

from dataclasses import dataclass

from langenv.control.pacing import PaceLimits
from langenv.errors import ConfigError
from langenv.speech.graph import PhraseGraph

__all__ = [
    "NATURAL",
    "Coverage",
    "coverage",
    "format_coverage",
    "leg_lengths",
    "natural_lengths",
    "speech_lengths",
]

NATURAL = 0.1
"""Audio paces within ``1 ± NATURAL`` count as a natural voice (the study's 0.1)."""

Intervals = tuple[tuple[float, float], ...]


def _merge(spans: list[tuple[float, float]], tol: float = 1e-9) -> Intervals:
    """Sorted, disjoint union of closed intervals (touching ones joined)."""
    out: list[tuple[float, float]] = []
    for lo, hi in sorted(spans):
        if out and lo <= out[-1][1] + tol:
            out[-1] = (out[-1][0], max(out[-1][1], hi))
        else:
            out.append((lo, hi))
    return tuple(out)


def speech_lengths(graph: PhraseGraph, u: str | None = None) -> Intervals:
    """Every speech length from ``u`` (default: start) to the end at a = 1, as merged intervals
    (s): the union over paths of ``[lo, hi]``, the path's pauses at their bounds."""
    sets: dict[str, Intervals] = {}
    for v in reversed(graph.order):
        lo, hi = graph.plan_range(v)
        kids = graph.children(v)
        if not kids:
            d = graph.duration[v]
            sets[v] = ((d, d),)
            continue
        spans = [(lo + a, hi + b) for w in kids for a, b in sets[w]]
        sets[v] = _merge(spans)
    return sets[graph.start if u is None else u]


def leg_lengths(graph: PhraseGraph, leg: str) -> Intervals:
    """Every length of the words of leg ``leg`` at a = 1 (s), as merged intervals: along each
    path, the slots of its vertices whose :meth:`~langenv.speech.graph.PhraseGraph.leg` is
    ``leg`` (pauses, and the wait before the next leg's words, at their planned bounds), from the
    start of the leg's first vertex to the start of the next leg's (the end of the speech for
    the last); a path that skips the leg's lines gives 0."""
    sets: dict[str, Intervals] = {}
    for v in reversed(graph.order):
        mine = graph.leg(v) == leg
        kids = graph.children(v)
        if not kids:
            d = graph.duration[v] if mine else 0.0
            sets[v] = ((d, d),)
            continue
        lo, hi = graph.plan_range(v) if mine else (0.0, 0.0)
        sets[v] = _merge([(lo + a, hi + b) for w in kids for a, b in sets[w]])
    return sets[graph.start]


def natural_lengths(speech: Intervals) -> Intervals:
    """The motion durations speech of these lengths at a = 1 can match at a natural voice
    (``|a - 1| <= NATURAL``), merged."""
    return _merge([(a / (1.0 + NATURAL), b / (1.0 - NATURAL)) for a, b in speech])


@dataclass(frozen=True)
class Coverage:
    """Motion durations a graph's speech can end together with.

    Attributes:
        speech: Speech lengths at a = 1 (s), merged intervals.
        natural: Motion durations reachable at ``|a - 1| <= NATURAL`` (s), merged intervals.
        full: Motion durations reachable at ``a_min <= a <= a_max`` (s), merged intervals.
        a_min, a_max: The pace limits used for ``full``.
        final_wait: Whether the last phrase waits for the motion (longer motions are met too,
            with silence before it).
    """

    speech: Intervals
    natural: Intervals
    full: Intervals
    a_min: float
    a_max: float
    final_wait: bool = False

    def covers(self, lo: float, hi: float, *, natural: bool = True) -> bool:
        """Whether every motion duration in ``[lo, hi]`` s is reachable (at a natural pace, or at
        any allowed pace)."""
        return any(a <= lo and hi <= b for a, b in (self.natural if natural else self.full))

    @property
    def natural_range(self) -> tuple[float, float]:
        """The widest gap-free range of ``natural`` (s)."""
        return max(self.natural, key=lambda ab: ab[1] - ab[0])

    @property
    def full_range(self) -> tuple[float, float]:
        """The widest gap-free range of ``full`` (s)."""
        return max(self.full, key=lambda ab: ab[1] - ab[0])


def coverage(graph: PhraseGraph, limits: PaceLimits | None = None) -> Coverage:
    """The graph's coverage at natural paces and within the pace limits.

    Args:
        graph: The phrase graph.
        limits: Audio pace bounds (default: the env's, :class:`~langenv.control.pacing.PaceLimits`).

    Raises:
        ConfigError: if the natural range ``1 ± NATURAL`` is not inside the pace limits.
    """
    lim = limits if limits is not None else PaceLimits()
    lo_n, hi_n = 1.0 - NATURAL, 1.0 + NATURAL
    if not (lim.a_min <= lo_n and hi_n <= lim.a_max):
        raise ConfigError(
            f"coverage: audio pace limits [{lim.a_min}, {lim.a_max}] must contain [{lo_n}, {hi_n}]"
        )
    speech = speech_lengths(graph)
    natural = _merge([(a / hi_n, b / lo_n) for a, b in speech])
    full = _merge([(a / lim.a_max, b / lim.a_min) for a, b in speech])
    return Coverage(speech, natural, full, lim.a_min, lim.a_max, graph.final_wait)


def _spans(intervals: Intervals) -> str:
    return ", ".join(f"{a:.1f}-{b:.1f} s" for a, b in intervals)


def format_coverage(cov: Coverage) -> str:
    """The coverage report, a few lines of text."""
    lines = [
        "coverage: motion durations the speech can end together with",
        f"  speech at a = 1:          {_spans(cov.speech)}",
        f"  at |a - 1| <= {NATURAL:g}:        {_spans(cov.natural)}",
        f"  at a in [{cov.a_min:g}, {cov.a_max:g}]:     {_spans(cov.full)}",
    ]
    if len(cov.natural) > 1:
        lo, hi = cov.natural_range
        lines.append(f"  widest natural range without gaps: {lo:.1f}-{hi:.1f} s")
    if cov.final_wait:
        lines.append(
            f"  longer motions: the last phrase waits for the motion (silence before it beyond "
            f"{cov.natural[-1][1]:.1f} s)"
        )
    return "\n".join(lines)
