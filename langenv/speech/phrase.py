"""A phrase graph's vertex (:class:`Phrase`: a phrase, a filler or a pause) and the numbers that
bound it (:mod:`langenv.speech.graph` builds graphs of them)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

from langenv.errors import PhraseGraphError

__all__ = [
    "DEFAULT_PAUSE",
    "KINDS",
    "MAX_FILLER",
    "MAX_PAUSE",
    "Phrase",
    "bounds_problem",
    "is_number",
]

DEFAULT_PAUSE = 1.0
"""Silence after each clip at a = 1 (s) when a graph file gives no ``pause`` (SPEC §2)."""

MAX_FILLER = 1.5
"""Longest clip a filler may have at a = 1 (s): fillers are short words."""

KINDS = ("phrase", "filler", "pause")
"""The kinds of phrase-graph vertices."""

MAX_PAUSE = 10.0
"""Longest silence (s at a = 1): a graph's ``pause`` and a pause vertex's maximum."""


def is_number(x: object) -> bool:
    """Whether ``x`` is a finite int or float (not a bool)."""
    return isinstance(x, int | float) and not isinstance(x, bool) and math.isfinite(x)


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
            problem = bounds_problem(self.bounds)
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


def bounds_problem(bounds: object) -> str:
    """Why ``bounds`` are not a pause's ``[min, max]`` seconds ('' when they are)."""
    if not isinstance(bounds, list | tuple) or len(bounds) != 2:
        return f"'pause' must be [min, max] seconds of silence, got {bounds!r}"
    lo, hi = bounds
    if not (is_number(lo) and is_number(hi)):
        return f"pause bounds must be numbers of seconds, got {list(bounds)!r}"
    if lo < 0.0 or hi < 0.0:
        return f"pause bounds must not be negative, got [{lo}, {hi}]"
    if lo > hi:
        return f"pause bounds are reversed: min {lo} > max {hi}"
    if hi > MAX_PAUSE:
        return f"pause max must be at most {MAX_PAUSE} s, got {hi}"
    return ""
