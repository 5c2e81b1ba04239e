"""Randomised variants of a phrase graph: the same script, said differently.

A learned aligner trained on one script learns that script's lengths. :func:`vary_graph` draws a
variant of a graph from a seeded generator, for training across worlds:

* **TTS rate**: every clip lasts ``1 / rate`` of its length, ``rate`` uniform in ``tts_rate``
  (a faster or slower voice; fillers stay within :data:`~langenv.speech.phrase.MAX_FILLER`);
* **pauses**: every pause vertex's bounds and the silence after each clip are scaled by one
  factor uniform in ``pause_scale`` (capped at 10 s, the graphs' limit);
* **wordings dropped**: each alternative of a choice (a child of a vertex with two or more) is
  left out with probability ``p_drop`` (one always stays); vertices no longer reachable go too;
* **wordings added**: each phrase that is an alternative of a choice gains, with probability
  ``p_add``, a sibling wording (id ``PHRASE~alt``) of ``add_length`` times its length with the same
  followers, where its parents have room (the graph's largest number of choices stays as is).

The variant keeps the graph's largest number of choices (:attr:`PhraseGraph.max_children`), so
the env's observation keeps its size; a draw that would change it is drawn again (at most
``tries`` times, then only the rate and the pauses vary). Variants live in memory only
(``path`` None); a learned aligner sees their ``t_min``/``t_max`` through the observation.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from langenv.errors import ConfigError, PhraseGraphError
from langenv.speech.graph import PhraseGraph
from langenv.speech.phrase import MAX_FILLER, MAX_PAUSE, Phrase
from langenv.speech.repeat import Repeat
from langenv.validation import dataclass_from_dict

__all__ = ["GraphVariation", "vary_graph"]


@dataclass(frozen=True)
class GraphVariation:
    """How :func:`vary_graph` varies a graph (module docstring).

    Attributes:
        p_drop: Probability that an alternative of a choice is left out, in [0, 1).
        p_add: Probability that an alternative gains a sibling wording, in [0, 1].
        add_length: The added wording's length relative to the phrase's, ``(lo, hi)``, > 0.
        pause_scale: Factor on pause bounds and the silence after clips, ``(lo, hi)``, >= 0.
        tts_rate: Speaking rate relative to the voice's, ``(lo, hi)``, > 0.
        tries: Draws before giving up on dropping and adding (>= 1).
    """

    p_drop: float = 0.15
    p_add: float = 0.15
    add_length: tuple[float, float] = (0.6, 1.5)
    pause_scale: tuple[float, float] = (0.6, 1.5)
    tts_rate: tuple[float, float] = (0.85, 1.2)
    tries: int = 20

    def __post_init__(self) -> None:
        owner = "GraphVariation"
        for name, hi_ok in (("p_drop", False), ("p_add", True)):
            v = getattr(self, name)
            if not (isinstance(v, int | float) and 0.0 <= v and (v <= 1.0 if hi_ok else v < 1.0)):
                bound = "[0, 1]" if hi_ok else "[0, 1)"
                raise ConfigError(f"{owner}.{name} must lie in {bound}, got {v!r}")
        for name, strict in (("add_length", True), ("pause_scale", False), ("tts_rate", True)):
            value = getattr(self, name)
            try:
                lo, hi = (float(x) for x in value)
            except (TypeError, ValueError):
                raise ConfigError(
                    f"{owner}.{name} must be a pair [lo, hi], got {value!r}"
                ) from None
            ok = math.isfinite(lo) and math.isfinite(hi) and lo <= hi and (lo > 0 or not strict)
            if not (ok and lo >= 0.0):
                raise ConfigError(f"{owner}.{name} must be finite, lo <= hi, lo > 0: {value!r}")
            object.__setattr__(self, name, (lo, hi))
        if not isinstance(self.tries, int) or self.tries < 1:
            raise ConfigError(f"{owner}.tries must be an int >= 1, got {self.tries!r}")

    @classmethod
    def from_dict(cls, data: Mapping[str, object], where: str = "GraphVariation") -> GraphVariation:
        """From plain data (a config's mapping); ConfigError naming ``where`` and the field."""
        return dataclass_from_dict(cls, data, where)


def vary_graph(
    graph: PhraseGraph, rng: np.random.Generator, variation: GraphVariation
) -> PhraseGraph:
    """A randomised variant of ``graph`` (module docstring), drawn from ``rng``.

    Args:
        graph: The script's graph.
        rng: The generator to draw from.
        variation: What varies and how much.

    Returns:
        A new graph in memory with ``graph.max_children`` choices at most and at least once.
    """
    rate = float(rng.uniform(*variation.tts_rate))
    scale = float(rng.uniform(*variation.pause_scale))
    own = PhraseGraph(  # the graph's own vertices: what a variant drops and adds to
        graph.source_phrases,
        graph.start,
        graph.duration,
        pause=graph.pause,
        voice=graph.voice,
    )
    for _ in range(variation.tries):
        try:
            out = _variant(graph, own, rng, variation, rate, scale, structural=True)
        except PhraseGraphError:
            continue
        if out.max_children == graph.max_children:
            return out
    return _variant(graph, own, rng, variation, rate, scale, structural=False)


def _scaled(bounds: tuple[float, float], scale: float) -> tuple[float, float]:
    """A pause's (or gap's) bounds times ``scale``, both at most the longest pause."""
    lo, hi = bounds
    return min(lo * scale, MAX_PAUSE), min(hi * scale, MAX_PAUSE)


def _variant(
    graph: PhraseGraph,
    own: PhraseGraph,
    rng: np.random.Generator,
    var: GraphVariation,
    rate: float,
    scale: float,
    *,
    structural: bool,
) -> PhraseGraph:
    nxt = {u: list(ph.next) for u, ph in own.phrases.items()}
    durations: dict[str, float] = {}
    phrases: dict[str, Phrase] = {}
    for u, ph in own.phrases.items():
        if ph.is_pause:
            lo, hi = ph.bounds  # type: ignore[misc]
            phrases[u] = Phrase(u, None, None, (), "pause", _scaled((lo, hi), scale))
        else:
            phrases[u] = ph
            d = graph.duration[u] / rate
            durations[u] = min(d, MAX_FILLER) if ph.kind == "filler" else d
    if structural:
        _add_wordings(own, rng, var, nxt, phrases, durations)
        for u in own.order:
            kids = nxt[u]
            if len(kids) >= 2:
                keep = [v for v in kids if rng.random() >= var.p_drop]
                nxt[u] = keep or [kids[int(rng.integers(len(kids)))]]
    live = _reachable(graph.start, nxt)
    final = {
        u: Phrase(u, ph.text, ph.audio, tuple(nxt[u]), ph.kind, ph.bounds)
        for u, ph in phrases.items()
        if u in live
    }
    repeats = [
        Repeat(r.name, kept, r.times, _scaled(r.gap, scale))
        for r in graph.repeats.values()
        if (kept := tuple(m for m in r.phrases if m in live))
    ]
    legs = {u: graph.leg_of[u.split("~", 1)[0]] for u in final} if graph.legs else {}
    intents = {
        u: graph.intent_of[u.split("~", 1)[0]]
        for u in final
        if u.split("~", 1)[0] in graph.intent_of
    }
    return PhraseGraph(
        final,
        graph.start,
        {u: d for u, d in durations.items() if u in live},
        pause=min(graph.pause * scale, MAX_PAUSE),
        voice=graph.voice,
        repeats=repeats,
        final_wait=graph.final_wait,
        legs=graph.legs,
        leg_of=legs,
        intents=intents,
    )


def _add_wordings(
    graph: PhraseGraph,
    rng: np.random.Generator,
    var: GraphVariation,
    nxt: dict[str, list[str]],
    phrases: dict[str, Phrase],
    durations: dict[str, float],
) -> None:
    """Sibling wordings of alternatives, in the graph's order (deterministic for a seed)."""
    room = graph.max_children
    parents: dict[str, list[str]] = {}
    for u in graph.order:
        for v in graph.children(u):
            parents.setdefault(v, []).append(u)
    for v in graph.order:
        ph = graph.phrases[v]
        ps = parents.get(v, [])
        if ph.kind != "phrase" or not ps or all(len(graph.children(p)) < 2 for p in ps):
            continue
        if rng.random() >= var.p_add:
            continue
        alt = f"{v}~alt"
        phrases[alt] = Phrase(alt, ph.text, ph.audio, (), "phrase", None)
        durations[alt] = durations[v] * float(rng.uniform(*var.add_length))
        nxt[alt] = list(nxt[v])
        for p in ps:
            if len(nxt[p]) < room:
                nxt[p].insert(nxt[p].index(v) + 1, alt)


def _reachable(start: str, nxt: Mapping[str, list[str]]) -> set[str]:
    seen, todo = {start}, [start]
    while todo:
        for v in nxt[todo.pop()]:
            if v not in seen:
                seen.add(v)
                todo.append(v)
    return seen
