"""Render a session's speech to audio: phrases at a time-varying audio pace, pitch preserved.

A *trace* gives the audio pace ``a`` (and optionally the motion ETC ``t_x``) at increasing times
``t`` (s); between samples the pace is linear in time, and it is held at its last value after the
trace. Speech starts at ``t[0]``; the output covers ``[t[0], t[-1]]`` (silence after the speech
ends) and is longer only when the speech is not over by ``t[-1]``: then it goes on at the last pace
until it is.

* :func:`render_speech` chooses the phrases as a live session would: at each phrase boundary, the
  graph's rule with the trace's ``t_x`` at that time, or the shortest path without ``t_x``.
* :func:`render_history` renders phrases already chosen (a finished env session's history).

Both stream the content (clips and silences, at base pace) block by block through
:class:`~langenv.speech.vocoder.VariableRateVocoder`, voiced as the graph's ``voice`` says
(stretched by the pace, or :class:`~langenv.speech.voice.NaturalVoice`). Silence goes through the
vocoder like a clip (zeros), so it lasts its base-pace length divided by the pace, as in the speech
timeline: a pause vertex sounds as the length chosen for it (:attr:`SpeechTimeline.pause_lengths
<langenv.speech.timeline.SpeechTimeline.pause_lengths>`, or the ``length`` of its utterance).
"""

from __future__ import annotations

import itertools
from collections.abc import Iterator, Mapping, Sequence
from typing import Any, Protocol

import numpy as np

from langenv.errors import ConfigError
from langenv.speech.audio import ClipLibrary
from langenv.speech.graph import PhraseGraph
from langenv.speech.timeline import SpeechTimeline, Utterance
from langenv.speech.voice import NaturalVoice
from langenv.validation import check_time_axis

__all__ = [
    "MAX_AUDIO_PACE",
    "MIN_AUDIO_PACE",
    "plan_speech",
    "render_history",
    "render_speech",
    "silence",
]

MIN_AUDIO_PACE = 0.25
"""Slowest audio pace a trace may ask for (the env keeps ``a`` within [0.6, 1.4]); it bounds how
far the speech can outlast the trace."""
MAX_AUDIO_PACE = 4.0
"""Fastest audio pace a trace may ask for."""

_PLAN_DT = 0.002  # s, timeline step when planning beyond the trace's samples
_BLOCK = 512  # output samples per vocoder pull


class _HasPhrase(Protocol):
    @property
    def phrase(self) -> str: ...


def _trace(t: Any, a: Any, t_x: Any = None) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """Validate a trace: 1-D, same length, finite, ``t`` increasing over at most
    ``MAX_SESSION_S`` with samples at least ``MIN_SAMPLE_SPACING`` apart, ``a`` within
    ``[MIN_AUDIO_PACE, MAX_AUDIO_PACE]``."""
    tt = np.asarray(t, dtype=np.float64)
    aa = np.asarray(a, dtype=np.float64)
    if tt.ndim != 1 or tt.size < 2:
        raise ConfigError(f"t must be 1-D with at least 2 samples, got shape {tt.shape}")
    if aa.shape != tt.shape:
        raise ConfigError(f"a must have the shape of t {tt.shape}, got {aa.shape}")
    if not np.all(np.isfinite(tt)) or np.any(np.diff(tt) <= 0.0):
        raise ConfigError("t must be finite and strictly increasing")
    check_time_axis(tt, "trace", ConfigError, lambda i: f"t[{i}]", from_zero=False)
    ok = np.isfinite(aa) & (aa >= MIN_AUDIO_PACE) & (aa <= MAX_AUDIO_PACE)
    if not np.all(ok):
        bad = int(np.flatnonzero(~ok)[0])
        raise ConfigError(
            f"a must be finite and > 0, within [{MIN_AUDIO_PACE:g}, {MAX_AUDIO_PACE:g}]; "
            f"got a[{bad}] = {float(aa[bad])!r}"
        )
    xx = None
    if t_x is not None:
        xx = np.asarray(t_x, dtype=np.float64)
        if xx.shape != tt.shape:
            raise ConfigError(f"t_x must have the shape of t {tt.shape}, got {xx.shape}")
        if not np.all(np.isfinite(xx)):
            bad = int(np.flatnonzero(~np.isfinite(xx))[0])
            raise ConfigError(f"t_x must be finite, got t_x[{bad}] = {xx[bad]!r}")
    return tt, aa, xx


def plan_speech(
    graph: PhraseGraph, t: Any, a: Any, t_x: Any = None, *, max_extra: float = 600.0
) -> list[Utterance]:
    """The phrases a live session would say along a trace, with their times.

    At each phrase boundary the next phrase follows the graph's rule with the trace's ``t_x``
    (linearly interpolated) at that time, and a pause entered takes the length of the graph's
    rule; without ``t_x``, the shortest path, pauses at their minimum. The pace over each
    interval ``[t_i, t_{i+1}]`` is the mean of its end values (exact for the linear pace).

    Args:
        graph: The phrase graph.
        t: Sample times (s), shape ``(n,)``, strictly increasing.
        a: Audio pace at those times, shape ``(n,)``, > 0.
        t_x: Motion ETC at those times (s), shape ``(n,)``, or None.
        max_extra: Longest time the speech may go on after ``t[-1]`` at the last pace (s).

    Returns:
        The utterances in order (pause vertices with their ``length``), times in the trace's
        clock (the first starts at ``t[0]``).

    Raises:
        ConfigError: naming the argument, for a malformed trace.
    """
    tt, aa, xx = _trace(t, a, t_x)
    tl = SpeechTimeline(graph)

    shortest = graph.shortest_path()
    on_shortest = dict(itertools.pairwise(shortest))

    def shortest_child(kids: tuple[str, ...]) -> str:
        u = tl.phrase
        v = on_shortest.get(u) if u is not None else None
        if v is not None and v in kids:
            return v
        return min(kids, key=graph.t_min)

    choice = shortest_child if xx is None else None
    pause = 0.0 if xx is None else None  # no target: every pause at its minimum
    for i in range(tt.size - 1):
        if tl.done:
            break
        tl.step(
            float(tt[i + 1] - tt[i]),
            0.5 * float(aa[i] + aa[i + 1]),
            choice,
            None if xx is None else float(xx[i]),
            pause,
        )
    extra = 0.0
    while not tl.done and extra < max_extra:
        t_x_now = None if xx is None else float(xx[-1]) - extra
        tl.step(_PLAN_DT, float(aa[-1]), choice, t_x_now, pause)
        extra += _PLAN_DT
    t0 = float(tt[0])
    return [Utterance(u.phrase, u.t_start + t0, u.t_end + t0, u.length) for u in tl.utterances()]


def silence(seconds: float, sr: int) -> np.ndarray:
    """``seconds`` of silence at ``sr`` Hz (float32 zeros; a pause vertex's sound)."""
    return np.zeros(max(0, round(seconds * sr)), np.float32)


def _content(
    graph: PhraseGraph,
    clips: ClipLibrary,
    ids: Sequence[str],
    pauses: Sequence[float],
    reopened: Mapping[int, float] | None = None,
) -> Iterator[tuple[np.ndarray, float | None]]:
    """Base-pace content, piece by piece: each clip, with the graph's pause after a clip that has
    a successor in the graph (also where a history cut short ends with it, as the live stream
    pushes it); each pause vertex as its silence (``pauses``: their lengths, in order). A clip
    with a successor comes with the seconds of silence after it (where a natural voice may wait,
    :meth:`NaturalVoice.clip <langenv.speech.voice.NaturalVoice.clip>`), every other piece with
    None. ``reopened`` gives the silence (s) before the words where the speech goes on after
    its end."""
    gap = silence(graph.pause, clips.sr)
    lengths = iter(pauses)
    for k, u in enumerate(ids):
        if reopened and k in reopened:
            yield silence(reopened[k], clips.sr), None
        if u in graph.pauses:
            yield silence(next(lengths), clips.sr), None
            continue
        if not graph.children(u):
            yield clips.clip(graph.phrases[u]), None
            continue
        yield clips.clip(graph.phrases[u]), gap.size / clips.sr
        if gap.size:
            yield gap, None


def render_history(
    graph: PhraseGraph,
    clips: ClipLibrary,
    history: Sequence[str | _HasPhrase],
    t: Any,
    a: Any,
    *,
    pause_lengths: Sequence[float] | None = None,
    progress: bool | None = False,
    vocoder_kw: dict[str, Any] | None = None,
) -> np.ndarray:
    """Render phrases already chosen, at the trace's audio pace.

    Args:
        graph: The phrase graph the phrases come from.
        clips: Their audio (its sample rate is the output's).
        history: Vertex ids said, in order, or objects with a ``phrase`` attribute
            (:class:`~langenv.speech.timeline.Utterance`, the evaluation's utterances, whose
            ``length`` gives a pause vertex's length); they must form a path from
            ``graph.start`` (it may stop before a final phrase), pause vertices included.
        pause_lengths: The lengths chosen for the pause vertices of ``history``, in order (s at
            a = 1; :attr:`SpeechTimeline.pause_lengths
            <langenv.speech.timeline.SpeechTimeline.pause_lengths>`); None: from the history's
            objects.
        t: Sample times (s), shape ``(n,)``, strictly increasing.
        a: Audio pace at those times, shape ``(n,)``, > 0.
        progress: Show a tqdm bar (None: only on a terminal).
        vocoder_kw: Extra keyword arguments of ``VariableRateVocoder``.

    Returns:
        Mono ``float32`` audio at ``clips.sr``, ``round((t[-1] - t[0]) sr)`` samples, longer when
        the speech outlasts the trace.

    Raises:
        ConfigError: naming the argument, for a malformed trace or a history that is not a path
            of ``graph`` from its start.
        AudioError: when a clip cannot be read or synthesised.
        ImportError: when ``langenv.speech.vocoder`` is not available.
    """
    tt, aa, _ = _trace(t, a)
    ids = [h if isinstance(h, str) else h.phrase for h in history]
    _check_path(graph, ids)
    pauses = _pause_lengths(graph, history, ids, pause_lengths)
    from langenv.speech.vocoder import VariableRateVocoder

    sr = clips.sr
    voc = VariableRateVocoder(sr, **(vocoder_kw or {}))
    clip_ids = [u for u in ids if u not in graph.pauses]
    total = float(sum(clips.clip(graph.phrases[u]).size for u in clip_ids)) / sr
    total += graph.pause * sum(1 for u in clip_ids if graph.children(u)) + sum(pauses)
    # content kept pushed ahead of the vocoder's read position: its window plus two blocks
    lookahead = 4.0 * (vocoder_kw or {}).get("n_fft", 1024) / sr + 3.0 * _BLOCK / sr
    voice = NaturalVoice(sr) if graph.voice == "natural" else None
    reopened = _reopen_silences(graph, history, ids, tt, aa)
    total += sum(reopened.values())
    feeder = _Feeder(voc, _content(graph, clips, ids, pauses, reopened), sr, lookahead, voice)
    n_trace = round((tt[-1] - tt[0]) * sr)
    # the speech may outlast the trace: at most its content at the last pace, plus slack
    n_cap = n_trace + int((total / float(aa[-1]) + 1.0) * sr)
    return _render_blocks(voc, feeder, tt, aa, n_trace, n_cap, progress)


def _pause_lengths(
    graph: PhraseGraph,
    history: Sequence[str | _HasPhrase],
    ids: Sequence[str],
    given: Sequence[float] | None,
) -> list[float]:
    """The lengths of the pause vertices of ``ids``: ``given``, else the history's ``length``s;
    each within its pause's bounds."""
    at = [k for k, u in enumerate(ids) if u in graph.pauses]
    if given is not None:
        lengths = [float(x) for x in given]
        if len(lengths) != len(at):
            raise ConfigError(
                f"pause_lengths: {len(lengths)} lengths for the {len(at)} pauses of the history"
            )
    else:
        lengths = []
        for k in at:
            length = getattr(history[k], "length", None)
            if length is None:
                raise ConfigError(
                    f"history[{k}]: pause {ids[k]!r} has no length; pass pause_lengths "
                    "(SpeechTimeline.pause_lengths) or utterances with their length"
                )
            lengths.append(float(length))
    for k, length in zip(at, lengths, strict=True):
        lo, hi = graph.slot_range(ids[k])
        if not lo - 1e-9 <= length <= hi + 1e-9:
            raise ConfigError(
                f"history[{k}]: pause {ids[k]!r} length {length!r} is outside its bounds "
                f"[{lo:g}, {hi:g}] s"
            )
    return lengths


def _reopens(graph: PhraseGraph, ids: Sequence[str], k: int) -> bool:
    """Whether the speech goes on at ``ids[k]`` after it ended at ``ids[k - 1]`` (the motion
    went back: :mod:`langenv.speech.repeat`)."""
    return k > 0 and graph.is_terminal(ids[k - 1]) and ids[k] == graph.reopen


def _reopen_silences(
    graph: PhraseGraph, history: Sequence[Any], ids: Sequence[str], tt: np.ndarray, aa: np.ndarray
) -> dict[int, float]:
    """Base-pace seconds of silence before each vertex where the speech goes on after its end:
    the trace's ``∫ a dt`` from the end of the words before to the start of the words after
    (0 for a history of ids without times)."""
    at = [k for k in range(1, len(ids)) if _reopens(graph, ids, k)]
    if not at:
        return {}
    cum = np.concatenate([[0.0], np.cumsum(0.5 * (aa[1:] + aa[:-1]) * np.diff(tt))])
    out: dict[int, float] = {}
    for k in at:
        a, b = getattr(history[k - 1], "t_end", None), getattr(history[k], "t_start", None)
        out[k] = (
            0.0 if a is None or b is None else float(np.interp(b, tt, cum) - np.interp(a, tt, cum))
        )
    return out


def _check_path(graph: PhraseGraph, ids: Sequence[str]) -> None:
    """Raise unless ``ids`` is a path of ``graph`` from its start phrase (where the speech goes
    on after its end, its reopen vertex may follow a last phrase)."""
    for k, u in enumerate(ids):
        if u not in graph.phrases:
            raise ConfigError(f"history[{k}]: {u!r} is not a phrase of {graph.path}")
        if k == 0 and u != graph.start:
            raise ConfigError(f"history[0]: {u!r} is not the start phrase {graph.start!r}")
        if k and u not in graph.children(ids[k - 1]) and not _reopens(graph, ids, k):
            raise ConfigError(f"history[{k}]: {u!r} does not follow {ids[k - 1]!r} in the graph")


class _Feeder:
    """Pushes base-pace content into a vocoder, ``lookahead`` seconds ahead of its read position,
    and finishes it when the content runs out. With a natural ``voice`` (None: the voice is
    stretched by the pace) each clip that may wait is declared to it as it is pushed, as the
    live stream declares it."""

    def __init__(
        self,
        voc: Any,
        pieces: Iterator[tuple[np.ndarray, float | None]],
        sr: int,
        lookahead: float,
        voice: NaturalVoice | None = None,
    ) -> None:
        self.voc, self.pieces, self.sr, self.lookahead = voc, pieces, sr, lookahead
        self.voice = voice
        self.pushed = 0  # content samples pushed so far
        self.finished = False

    def feed(self, force: bool = False) -> None:
        """Push pieces until the lookahead is covered (at least one with ``force``)."""
        voc = self.voc
        while not self.finished and (
            force or self.pushed / self.sr - voc.content_time < self.lookahead
        ):
            force = False
            piece = next(self.pieces, None)
            if piece is None:
                voc.finish()
                self.finished = True
                continue
            y, silence_after = piece
            if self.voice is not None and silence_after is not None:
                start = self.pushed / self.sr
                self.voice.clip(start, start + y.size / self.sr, silence_after)
            voc.push(y)
            self.pushed += y.size

    def pull(self, n: int, pace: float) -> np.ndarray:
        """Up to ``n`` samples at ``pace`` (the speech pace; voiced by :attr:`voice` when set),
        topping the content up if the vocoder starves while content remains."""
        self.feed()
        parts: list[np.ndarray] = []
        got = 0
        while True:
            if self.voice is not None:
                y, _ = self.voice.block(self.voc, n - got, pace)
            else:
                y = np.asarray(self.voc.pull(n - got, pace))
            parts.append(y)
            got += y.size
            if got >= n or self.finished:
                break
            self.feed(force=True)
        return parts[0] if len(parts) == 1 else np.concatenate(parts)


def _render_blocks(
    voc: Any,
    feeder: _Feeder,
    tt: np.ndarray,
    aa: np.ndarray,
    n_trace: int,
    n_cap: int,
    progress: bool | None,
) -> np.ndarray:
    """Pull the vocoder block by block at the trace's pace: the trace's span, then whatever the
    speech still holds (up to ``n_cap`` samples)."""
    from tqdm import tqdm

    sr = feeder.sr
    out = np.zeros(n_trace, np.float32)
    extra: list[np.ndarray] = []
    produced = 0
    with tqdm(
        total=round(n_trace / sr, 2),
        unit="s",
        desc="render",
        disable=None if progress is None else not progress,
        bar_format="{l_bar}{bar}| {n:.1f}/{total:.1f} s [{elapsed}<{remaining}]",
    ) as bar:
        while not voc.done and produced < n_cap:
            n = min(_BLOCK, n_trace - produced) if produced < n_trace else _BLOCK
            pace = float(np.interp(tt[0] + (produced + 0.5 * n) / sr, tt, aa))
            y = feeder.pull(n, pace)
            if y.size == 0:
                break  # finished and drained
            if produced < n_trace:
                k = min(y.size, n_trace - produced)
                out[produced : produced + k] = y[:k]
                if k < y.size:
                    extra.append(np.asarray(y[k:], np.float32))
                bar.update(k / sr)
            else:
                extra.append(np.asarray(y, np.float32))
            produced += y.size
    if extra:
        out = np.concatenate([out, *extra])
    return out


def render_speech(
    graph: PhraseGraph,
    clips: ClipLibrary,
    t: Any,
    a: Any,
    t_x: Any = None,
    *,
    progress: bool | None = False,
    vocoder_kw: dict[str, Any] | None = None,
) -> np.ndarray:
    """Render the speech a live session would say along a trace.

    The phrases follow :func:`plan_speech` (the graph's rule with the trace's ``t_x`` at each
    boundary, or the shortest path), then play through the vocoder as :func:`render_history`.

    Args:
        graph: The phrase graph.
        clips: Phrase audio (its sample rate is the output's).
        t: Sample times (s), shape ``(n,)``, strictly increasing.
        a: Audio pace, shape ``(n,)``, > 0.
        t_x: Motion ETC (s), shape ``(n,)``, or None.
        progress: Show a tqdm bar (None: only on a terminal).
        vocoder_kw: Extra keyword arguments of ``VariableRateVocoder``.

    Returns:
        Mono ``float32`` audio at ``clips.sr`` (see :func:`render_history` for its length).
    """
    plan = plan_speech(graph, t, a, t_x)
    return render_history(graph, clips, plan, t, a, progress=progress, vocoder_kw=vocoder_kw)
