"""How a speech pace is heard: the voice stretched (the paper) or a natural voice that waits.

The pace law sets the *speech pace* ``a``: how fast the speech timeline moves through its
content (clips, the silences after them and pause vertices, in seconds at ``a = 1``). How that
pace is *voiced* is a property of the phrase graph (its ``voice`` key):

``"stretch"`` (the study's graphs; the default)
    The voice is time-stretched by ``a`` at every instant, as in the paper: a resisting person
    hears slow speech.
``"natural"`` (the product's scripts)
    As a person speaks: a clip that has a successor is said at ``max(a, SLOWEST)`` from the
    moment the timeline starts it (:data:`SLOWEST` = 0.9: a voice at most 10 % slower than its
    natural rate, which a listener hears as natural), so the voice never drags, and once its
    words are said the voice *waits*
    in silence until the timeline reaches the clip's end. The timeline, its ETC ``t_a``, every
    phrase boundary and the speech's end are exactly those of ``"stretch"``: only where the
    silence falls inside a clip's slot changes. The last clip (no successor) follows ``a``
    itself, so the voice ends when the speech ends.

The rule is causal (it needs only the pace so far and where the current clip ends), so the live
audio stream and the offline rendering apply it block by block (:class:`NaturalVoice`), and the
evaluation applies it to a session's log (:func:`voice_rate`) to measure how natural the voice
was.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any, Literal

import numpy as np

from langenv.errors import ConfigError

__all__ = [
    "SLOWEST",
    "VOICES",
    "WAIT_AFTER",
    "NaturalVoice",
    "Voice",
    "check_voice",
    "voice_rate",
    "waiting_spans",
    "words_heard",
]

Voice = Literal["stretch", "natural"]
VOICES: tuple[Voice, ...] = ("stretch", "natural")
"""The ways a speech pace may be voiced (see the module docstring)."""

_EPS = 1e-9

SLOWEST = 0.9
"""The slowest rate at which the natural voice says a clip that has a successor (1 - 0.1, the
tolerance within which the study counts a pace as natural): slower speech is a wait instead."""

WAIT_AFTER = 0.06
"""How far into the silence after a clip the natural voice goes before it waits (s, at most that
silence): the vocoder's last frames of the clip (its window is 46 ms) are heard before the wait,
not after it."""


def check_voice(value: object, where: str) -> Voice:
    """``value`` as a :data:`Voice`.

    Raises:
        ConfigError: naming ``where``, for anything but one of :data:`VOICES`.
    """
    if value not in VOICES:
        raise ConfigError(f"{where}: voice must be one of {list(VOICES)}, got {value!r}")
    return value


class NaturalVoice:
    """The natural voice, block by block: how much of the vocoder to pull, at what pace.

    The caller keeps the vocoder and declares each clip with a successor (:meth:`clip`: where
    its words start and end in the content) as the clips are pushed. For every output block it
    calls :meth:`block` with the speech pace of the block; the speech's own position (content
    seconds the timeline has covered, the integral of ``a``) is kept here. Outside those clips
    (the silence after a clip, pause vertices, the last clip) the voice follows ``a``.

    Args:
        sr: Sample rate (Hz) of content and output.
    """

    def __init__(self, sr: int) -> None:
        if isinstance(sr, bool) or not isinstance(sr, int) or sr <= 0:
            raise ConfigError(f"sr must be a positive integer (Hz), got {sr!r}")
        self.sr = sr
        self.speech_pos = 0.0
        """Content seconds the speech timeline has covered (the integral of ``a``)."""
        self._spans: list[tuple[float, float, float]] = []  # (start, wait point, known end)
        self._k = 0  # first clip whose end the speech has not reached
        self._stop: float | None = None  # where the voice stopped in clip k, once it has

    def clip(self, start: float, end: float, silence_after: float = 0.0) -> None:
        """Declare a clip with a successor: its words span content ``[start, end)`` (s), and
        ``silence_after`` seconds of silence follow them (the voice waits up to
        :data:`WAIT_AFTER` into it). The content after that silence is not yet known when the
        clip starts (a live session chooses it at the clip's end): the voice stops early enough
        that the vocoder never reads past it, so a short silence (``pause`` under about 0.2 s)
        moves the wait before the clip's last samples rather than starving a live stream.

        Raises:
            ConfigError: if the span is empty or clips are not declared in order.
        """
        if not end > start or (self._spans and start < self._spans[-1][1] - _EPS):
            last = self._spans[-1] if self._spans else None
            raise ConfigError(
                f"NaturalVoice.clip: clips must be non-empty and in order, got "
                f"[{start}, {end}) after {last}"
            )
        after = max(float(silence_after), 0.0)
        self._spans.append((float(start), float(end) + min(after, WAIT_AFTER), float(end) + after))

    def block(self, voc: Any, n: int, a: float) -> tuple[np.ndarray, bool]:
        """Up to ``n`` output samples while the speech moves at pace ``a``.

        Args:
            voc: The :class:`~langenv.speech.vocoder.VariableRateVocoder` holding the content.
            n: Samples wanted.
            a: The speech pace over this block (> 0).

        Returns:
            ``(samples, starved)``: float32 audio, ``n`` samples unless the vocoder ran out of
            content; ``starved`` when it did so before its content was finished.
        """
        parts: list[np.ndarray] = []
        left = n
        while left > 0:
            m, pace, silent = self._plan(left, a, voc)
            y = np.zeros(m, np.float32) if silent else np.asarray(voc.pull(m, pace), np.float32)
            if y.size:
                parts.append(y)
                self.speech_pos += a * y.size / self.sr
                left -= y.size
            if y.size < m:
                out = np.concatenate(parts) if parts else np.zeros(0, np.float32)
                return out, not voc.done
        return np.concatenate(parts), False

    def _plan(self, n: int, a: float, voc: Any) -> tuple[int, float, bool]:
        """``(samples, pace, silent)`` for the next piece of a block of ``n`` samples."""
        spans, p, voice_pos = self._spans, self.speech_pos, voc.content_time
        while self._k < len(spans) and p >= self._wait_end() - _EPS:
            self._k += 1
            self._stop = None
        if self._k == len(spans):
            return n, a, False
        start, wait, known = spans[self._k]
        if p < start - _EPS:  # the speech is in the silence before the clip: follow a
            if voice_pos < start - _EPS:
                return self._upto(n, start - voice_pos, a), a, False
            return self._upto(n, start - p, a), a, True
        if self._stop is None:  # the clip's words: never slower than natural
            pace = max(a, SLOWEST)
            stop = min(wait, known - self._reach(voc, pace))
            if voice_pos < stop - 0.5 / self.sr:
                return self._upto(n, stop - voice_pos, pace), pace, False
            # the wait lasts until the speech reaches the voice (or its wait point, as it ends
            # within half a sample of it)
            self._stop = max(p, wait if stop == wait else max(stop, voice_pos))
            if p >= self._stop - _EPS:  # nothing to wait for: on to the rest of the content
                return self._plan(n, a, voc)
        return self._upto(n, self._stop - p, a), a, True  # said: wait for the speech

    def _wait_end(self) -> float:
        """Where the wait of clip ``k`` ends: where its voice stopped, else its wait point."""
        return self._stop if self._stop is not None else self._spans[self._k][1]

    def _reach(self, voc: Any, pace: float) -> float:
        """Content (s) past its read position the vocoder needs to emit output at ``pace``: its
        half window at the output and at the content side, plus a hop's slack for each."""
        half = 0.5 * getattr(voc, "n_fft", 0)
        return (pace + 1.0) * (half + getattr(voc, "hop", 0)) / self.sr

    def _upto(self, n: int, content: float, pace: float) -> int:
        """Samples (1..n) that cover ``content`` seconds of content at ``pace``."""
        return min(n, max(1, math.ceil(content * self.sr / pace - 1e-6)))


def waiting_spans(
    t: np.ndarray, speech_done: np.ndarray, clips: Sequence[tuple[float, float]]
) -> list[tuple[float, float]]:
    """The ``(t_start, t_end)`` of the clips a natural voice may wait after: every clip but one
    the speech ends with (at the first sample from its end the speech is over; a last phrase,
    once more if the speech went on after its end), which follows ``a``.

    Args:
        t: Sample times (s), shape ``(n,)``, increasing.
        speech_done: Whether the speech is over at those times, shape ``(n,)``.
        clips: The session's clips' spans, in order.
    """
    t = np.asarray(t, dtype=np.float64)
    done = np.asarray(speech_done, dtype=bool)
    at = np.searchsorted(t, [end for _, end in clips])
    return [c for c, k in zip(clips, at.tolist(), strict=True) if not (k < t.size and done[k])]


def voice_rate(
    t: np.ndarray, a: np.ndarray, spans: Sequence[tuple[float, float]]
) -> tuple[np.ndarray, np.ndarray]:
    """The natural voice's rate at each sample of a session's log.

    Each sample stands for the interval until the next one (zero-order hold, as in the
    evaluation's metrics). Inside each span ``[t_start, t_end)`` of a clip with a successor the
    voice says the clip at ``max(a, SLOWEST)`` until it has said as much as the speech covers in the
    span, then waits (rate 1: silence, nothing stretched); elsewhere it follows ``a``. It leaves
    out what :class:`NaturalVoice` adds at a sample's scale: its wait starts up to
    :data:`WAIT_AFTER` into the silence after the clip, or before the clip's last words where
    that silence is too short for the vocoder's read-ahead (a graph ``pause`` under about 0.2 s).

    Args:
        t: Sample times (s), shape ``(n,)``, strictly increasing.
        a: Speech pace at those times, shape ``(n,)``.
        spans: ``(t_start, t_end)`` of the clips that wait (s), in order, not overlapping.

    Returns:
        ``(v, waiting)``: the voice's rate, shape ``(n,)`` (``a`` outside the spans), and whether
        it waits in silence, shape ``(n,)``, bool.
    """
    t = np.asarray(t, dtype=np.float64)
    a = np.asarray(a, dtype=np.float64)
    if t.shape != a.shape or t.ndim != 1 or t.size < 2:
        raise ConfigError(
            f"t and a must have the same shape (n,), n >= 2; got {t.shape}, {a.shape}"
        )
    v = a.copy()
    waiting = np.zeros(t.shape, dtype=bool)
    ends = np.append(t[1:], t[-1] + (t[-1] - t[-2]))
    for t0, t1 in spans:
        lo = int(np.searchsorted(t, t0, side="right")) - 1
        hi = int(np.searchsorted(t, t1, side="left"))
        lo = max(lo, 0)
        if hi <= lo:
            continue
        idx = np.arange(lo, hi)
        w = np.clip(np.minimum(ends[idx], t1) - np.maximum(t[idx], t0), 0.0, None)
        covered = float(np.sum(a[idx] * w))
        rate = np.maximum(a[idx], SLOWEST)
        said = np.cumsum(rate * w)
        before = said - rate * w  # said when each sample starts
        speaking = before < covered - _EPS
        v[idx] = np.where(speaking, rate, 1.0)
        waiting[idx] = ~speaking
    return v, waiting


def words_heard(
    t: np.ndarray, waiting: np.ndarray, spans: Sequence[tuple[float, float]], until: float
) -> float:
    """Seconds in ``[t[0], until)`` in which words of the given clips are heard.

    The clips' words span ``[t_start, t_end)`` each (the silence after a clip is not part of
    it); inside them the voice is silent where it waits (``waiting``, from :func:`voice_rate`).
    Each sample holds its state until the next one (zero-order hold; the last one for the
    interval before it), as in the evaluation's metrics; the spans' ends are exact.

    Args:
        t: Sample times (s), shape ``(n,)``, ``n >= 2``, strictly increasing.
        waiting: Whether the voice waits at each sample, shape ``(n,)``, bool.
        spans: ``(t_start, t_end)`` of the clips whose words count (s), not overlapping.
        until: End of the window (s).

    Returns:
        The seconds, ``>= 0``.
    """
    t = np.asarray(t, dtype=np.float64)
    waiting = np.asarray(waiting, dtype=bool)
    if t.ndim != 1 or t.size < 2 or waiting.shape != t.shape:
        raise ConfigError(
            f"t and waiting must have the same shape (n,), n >= 2; got {t.shape}, {waiting.shape}"
        )
    t0 = float(t[0])
    cut = [(max(float(a), t0), min(float(b), until)) for a, b in spans]
    cut = [(a, b) for a, b in cut if b > a]
    said = float(sum(b - a for a, b in cut))
    if not cut or not waiting.any():
        return said
    ends = np.append(t[1:], t[-1] + (t[-1] - t[-2]))
    silent = 0.0
    for a, b in cut:  # the waits inside the words' spans, each sample's overlap exactly
        lo = max(int(np.searchsorted(t, a, side="right")) - 1, 0)
        hi = int(np.searchsorted(t, b, side="left"))
        idx = np.arange(lo, hi)
        idx = idx[waiting[idx]]
        if idx.size:
            overlap = np.minimum(ends[idx], b) - np.maximum(t[idx], a)
            silent += float(np.sum(np.clip(overlap, 0.0, None)))
    return max(0.0, said - silent)
