"""The robot's speech as a live audio stream: the timeline's phrases through the block vocoder.

A :class:`SpeechStream` follows one session. As the session's :class:`SpeechTimeline` starts a
phrase, its clip is pushed to a :class:`~langenv.speech.vocoder.VariableRateVocoder`, followed by
the graph's pause when the phrase has a successor (a pause vertex: its silence, pushed as it
elapses, since its length is chosen as it goes); the loop records the audio pace of every step (a
graph with ``voice: natural`` is voiced by :class:`~langenv.speech.voice.NaturalVoice`). Output
sample ``j`` (at ``j / sr`` s into the session) is rendered in blocks of :data:`BLOCK` samples at
the session's audio pace at the middle of its block (linear between the recorded steps), exactly as
:func:`langenv.speech.render.render_history` renders a finished session, so the live audio equals
the offline rendering of the same trace.

A block is rendered once the session is ``lag`` seconds past the block's end: by then the
timeline has chosen the phrase the vocoder reads ahead into (it reads about ``(a + 1) n_fft / 2``
samples of content past the one it plays, 50 ms at ``a = 1.4``). The speech is heard ``lag`` plus
the sound card's buffer after the simulation says it, 0.2 s in all by default.
"""

from __future__ import annotations

import numpy as np

from langenv.errors import ConfigError
from langenv.speech.audio import ClipLibrary
from langenv.speech.graph import PhraseGraph
from langenv.speech.vocoder import VariableRateVocoder
from langenv.speech.voice import NaturalVoice

__all__ = ["BLOCK", "DEFAULT_LAG", "SpeechStream"]

BLOCK = 512
"""Output samples per vocoder pull (as in the offline rendering)."""

DEFAULT_LAG = 0.15
"""Seconds the audio is rendered behind the simulation (see the module docstring)."""


class SpeechStream:
    """One session's speech, rendered as the session runs.

    Args:
        graph: The phrase graph the session speaks.
        clips: Its audio (its sample rate is the stream's).
        start_sample: Sample of the output clock at which the session starts (the stream emits
            silence before it); the output clock counts samples from 0.
        lag: Render this many seconds behind the session (>= 0.1 s).

    Attributes:
        sr: Sample rate (Hz).
        next_sample: Output-clock sample the next render starts at.
        starved: Pulls that got less audio than asked although the speech was not over (the
            content was not known yet; raise ``lag`` if this is ever non-zero).
    """

    def __init__(
        self,
        graph: PhraseGraph,
        clips: ClipLibrary,
        *,
        start_sample: int = 0,
        lag: float = DEFAULT_LAG,
    ) -> None:
        if not lag >= 0.1:
            raise ConfigError(f"lag must be >= 0.1 s (the vocoder reads ahead), got {lag!r}")
        if start_sample < 0:
            raise ConfigError(f"start_sample must be >= 0, got {start_sample!r}")
        self.graph, self.clips, self.sr, self.lag = graph, clips, clips.sr, float(lag)
        self.start_sample = int(start_sample)
        self.next_sample = self.start_sample
        self.starved = 0
        self._voc = VariableRateVocoder(self.sr)
        self._voice = NaturalVoice(self.sr) if graph.voice == "natural" else None
        self._content = 0  # content samples pushed so far
        self._gap = np.zeros(round(graph.pause * self.sr), np.float32)
        self._pushed = 0  # phrases of the timeline's path pushed so far
        self._pauses_pushed = 0  # pause vertices among them
        self._silence = 0  # samples of the current pause vertex pushed so far
        self._t = np.zeros(1024)
        self._a = np.ones(1024)
        self._n = 0
        self._k = 0  # trace interval of the last pace looked up

    # ------------------------------------------------------------------ input
    def record(
        self,
        t: float,
        a: float,
        path: tuple[str, ...],
        speech_done: bool,
        pause_lengths: tuple[float, ...] = (),
    ) -> None:
        """The session at its time ``t`` (s, increasing): audio pace ``a``, vertices started so
        far (the timeline's ``path``), whether the speech is over, and the lengths of the pause
        vertices of ``path`` (the timeline's ``pause_lengths``: a pause that lasts counts with
        what has elapsed of it, and its silence is pushed as it elapses)."""
        if self._n and t <= self._t[self._n - 1]:
            last = self._t[self._n - 1]
            raise ConfigError(f"SpeechStream.record: t must increase, got {t} after {last}")
        if self._n == self._t.size:
            self._t = np.concatenate([self._t, np.zeros(self._t.size)])
            self._a = np.concatenate([self._a, np.ones(self._a.size)])
        self._t[self._n], self._a[self._n] = t, a
        self._n += 1
        if self._voc.finished and self._pushed < len(path):  # the speech goes on after its end
            self._resume(t, a)
        while self._pushed < len(path):
            phrase = path[self._pushed]
            if phrase in self.graph.pauses:  # a pause vertex: its silence, as it elapses
                k = self._pauses_pushed
                if k >= len(pause_lengths):
                    raise ConfigError(
                        f"SpeechStream.record: pause {phrase!r} entered without its length "
                        "(pass the timeline's pause_lengths)"
                    )
                want = round(pause_lengths[k] * self.sr)
                if want > self._silence:
                    self._push(np.zeros(want - self._silence, np.float32))
                    self._silence = want
                if self._pushed + 1 == len(path):
                    break  # the pause goes on
                self._pauses_pushed += 1
                self._silence = 0
            else:
                clip = self.clips.clip(self.graph.phrases[phrase])
                if self._voice is not None and self.graph.children(phrase):
                    start = self._content / self.sr
                    gap = self._gap.size / self.sr
                    self._voice.clip(start, start + clip.size / self.sr, gap)
                self._push(clip)
                if self.graph.children(phrase) and self._gap.size:
                    self._push(self._gap)
            self._pushed += 1
        if speech_done and not self._voc.finished:
            self._voc.finish()

    def _resume(self, t: float, a: float) -> None:
        """The vocoder takes content again (the speech went on after its end; ``t``: the step's
        time, when the new words are recorded, up to a step after they start): first the
        silence from the output already rendered to ``t`` at pace ``a``, at least a frame (no
        frame already emitted may reach the new words)."""
        self._voc.resume()
        rendered = float(self._t[0]) + (self.next_sample - self.start_sample) / self.sr
        n = max(self._voc.n_fft, round(a * (t - rendered) * self.sr))
        self._push(np.zeros(n, np.float32))

    def _push(self, y: np.ndarray) -> None:
        self._voc.push(y)
        self._content += y.size

    def trace(self) -> tuple[np.ndarray, np.ndarray]:
        """The recorded times (s) and audio paces, shape (n,) each (copies)."""
        return self._t[: self._n].copy(), self._a[: self._n].copy()

    # ------------------------------------------------------------------ output
    def render(self, session_time: float, limit: int) -> np.ndarray:
        """The output from :attr:`next_sample` on, as far as ``session_time`` (s, the session's
        latest recorded time) allows, at most ``limit`` samples (whole blocks); float32."""
        parts: list[np.ndarray] = []
        room = limit
        if self.next_sample < self.start_sample and room > 0:  # silence before the session
            n = min(room, self.start_sample - self.next_sample)
            parts.append(np.zeros(n, np.float32))
            self.next_sample += n
            room -= n
        while room >= BLOCK and self._n:
            produced = self.next_sample - self.start_sample
            t0 = float(self._t[0])
            if t0 + (produced + BLOCK) / self.sr + self.lag > session_time:
                break
            if self._voc.done:
                y = np.zeros(BLOCK, np.float32)
            else:
                pace = self._pace_at(t0 + (produced + 0.5 * BLOCK) / self.sr)
                if self._voice is not None:
                    y, _ = self._voice.block(self._voc, BLOCK, pace)
                else:
                    y = self._voc.pull(BLOCK, pace)
                if y.size < BLOCK and not self._voc.done:
                    self.starved += 1
                    if y.size == 0:
                        break
            parts.append(y)
            self.next_sample += y.size
            room -= y.size
        return np.concatenate(parts) if parts else np.zeros(0, np.float32)

    def _pace_at(self, t: float) -> float:
        """The recorded pace at time ``t``: linear between samples, held after the last."""
        n, tt, aa = self._n, self._t, self._a
        if t <= tt[0]:
            return float(aa[0])
        k = self._k
        while k + 1 < n and tt[k + 1] <= t:
            k += 1
        self._k = k
        if k + 1 >= n:
            return float(aa[n - 1])
        return float(np.interp(t, tt[k : k + 2], aa[k : k + 2]))
