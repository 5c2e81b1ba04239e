"""The real-time loop: the env stepped on the wall clock, its speech streamed to a sound card.

Every env step (one 2 ms tick at 500 Hz decisions, ``500 / decision_hz`` ticks otherwise) is due
at its simulated start time on the monotonic clock; the loop sleeps until a step is due, runs it
(policy, env), records the speech timeline into the :class:`~langenv.live.stream.SpeechStream`
and, between steps, renders the audio the stream can give into the
:class:`~langenv.live.ring.AudioRing` that the sink (sound card or WAV) reads on its own clock.
The sink starts once the ring holds :data:`PREFILL` seconds.

* A tick is **late** when its step starts more than one tick period (2 ms) after it was due. The
  loop never skips physics: a late loop runs the steps it owes back to back and catches up.
* An **underrun** is a sink read that found the ring short (silence was played).

When a session ends, the arm rests for ``rest`` seconds, then the next session starts (seed + 1),
its speech continuing the same audio clock.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from langenv.errors import ConfigError
from langenv.live.ring import AudioRing
from langenv.live.sinks import AudioSink
from langenv.live.stream import BLOCK, DEFAULT_LAG, SpeechStream

__all__ = ["PREFILL", "TRACE_COLUMNS", "LiveHooks", "LoopReport", "RealTimeLoop"]

PREFILL = 0.05
"""Seconds of audio in the ring before the sink starts."""

TICK = 0.002
"""Control period (s)."""

TRACE_COLUMNS = ("session", "t", "p", "a", "cooperation", "em", "fx", "fy", "fz", "phrase")
"""Columns of the rows the loop records (``record=True``): the session's index, its time (s),
the paces, cooperation, EM (s), the person's force on the handle (N) and the phrase being said
(empty in pauses)."""


@dataclass(frozen=True)
class LoopReport:
    """What a run of the loop measured.

    Attributes:
        wall_s: Wall-clock time the loop ran (s).
        sim_s: Simulated time (s).
        ticks: 2 ms ticks run.
        late_ticks: Ticks whose step started more than one tick period late.
        max_lag_ms: Largest lateness of a step (ms).
        underruns: Sink reads that found the ring short.
        missing_ms: Audio those reads lacked (ms, played as silence).
        device_xruns: Underruns the sound card reported itself.
        starved: Vocoder pulls short of content (0 unless the stream lag is too small).
        sessions: Sessions finished.
        audio_s: Seconds of audio rendered.
        ams: AM (speech end - motion end, s) of each finished session; NaN if it was cut off.
    """

    wall_s: float
    sim_s: float
    ticks: int
    late_ticks: int
    max_lag_ms: float
    underruns: int
    missing_ms: float
    device_xruns: int
    starved: int
    sessions: int
    audio_s: float
    ams: tuple[float, ...] = ()

    def summary(self) -> str:
        """One line for the terminal."""
        share = 100.0 * self.late_ticks / self.ticks if self.ticks else 0.0
        return (
            f"{self.sim_s:.1f} s in real time ({self.wall_s:.1f} s wall): {self.ticks} ticks, "
            f"late ticks {self.late_ticks} ({share:.2f} %, max lag {self.max_lag_ms:.1f} ms), "
            f"audio underruns {self.underruns} ({self.missing_ms:.0f} ms missing, device "
            f"xruns {self.device_xruns}), {self.audio_s:.1f} s of audio, "
            f"vocoder starved {self.starved}, sessions finished {self.sessions}"
            + (" (AM " + ", ".join(f"{am:+.2f}" for am in self.ams) + " s)" if self.ams else "")
        )


class LiveHooks:
    """What a front end (viewer, terminal) adds to the loop; the default does nothing."""

    def running(self) -> bool:
        """False to stop the loop (e.g. the window was closed)."""
        return True

    def frame(self, loop: RealTimeLoop) -> None:
        """Called about 60 times a second of wall time (draw, read the mouse)."""

    def session_end(self, loop: RealTimeLoop, info: dict[str, Any]) -> None:
        """Called when a session ends (``info``: the env's last info)."""


class RealTimeLoop:
    """Runs an env and a policy in real time with the speech streamed to a sink.

    Args:
        env: A ``LangCtrl-v0`` env (``gymnasium.make`` or the class itself).
        policy: Offers ``act(observation)`` and ``reset()``.
        make_sink: Builds the sink from the ring and the sample rate.
        seed: Seed of the first session (the next ones use seed + 1, ...).
        rest: Seconds between the end of a session and the start of the next.
        lag: The speech stream's lag (s).
        prefill: Seconds of audio in the ring before the sink starts (also the most the loop
            can fall behind before the sound underruns).
        hooks: The front end.
        record: Keep one row per step in :attr:`rows` (see :data:`TRACE_COLUMNS`).
    """

    def __init__(
        self,
        env: Any,
        policy: Any,
        make_sink: Callable[[AudioRing, int], AudioSink],
        *,
        seed: int = 0,
        rest: float = 2.0,
        lag: float = DEFAULT_LAG,
        prefill: float = PREFILL,
        hooks: LiveHooks | None = None,
        record: bool = False,
    ) -> None:
        if not (math.isfinite(rest) and rest >= 0.0):
            raise ConfigError(f"rest must be finite and >= 0 s, got {rest!r}")
        if not (math.isfinite(prefill) and 0.0 < prefill <= 0.9):
            raise ConfigError(f"prefill must be in (0, 0.9] s, got {prefill!r}")
        self.prefill = float(prefill)
        self.record = bool(record)
        self.rows: list[tuple[Any, ...]] = []
        self.env, self.policy = env, policy
        self.base: Any = env.unwrapped
        self.seed, self.rest, self.lag = int(seed), float(rest), float(lag)
        self.hooks = hooks if hooks is not None else LiveHooks()
        self.sr = int(self.base.clips.sr)
        self.ring = AudioRing(self.sr)  # 1 s
        self.sink = make_sink(self.ring, self.sr)
        self.step_dt = self.base.ticks_per_step * TICK
        self.info: dict[str, Any] = {}
        self.sessions = 0
        self.ams: list[float] = []
        self._obs: np.ndarray = np.zeros(0)
        self._stream: SpeechStream | None = None
        self._session_start = 0.0  # loop time the session started (s)
        self._ended_at: float | None = None

    @property
    def stream(self) -> SpeechStream:
        """The current session's speech stream."""
        assert self._stream is not None
        return self._stream

    def _new_session(self, at: float) -> None:
        """Reset the env and the policy; the session starts at loop time ``at`` (s)."""
        obs, info = self.env.reset(seed=self.seed + self.sessions)
        self.policy.reset()
        self._obs, self.info = obs, info
        first = self._stream.next_sample if self._stream is not None else 0
        stream = SpeechStream(
            self.base.graph, self.base.clips, start_sample=round(at * self.sr), lag=self.lag
        )
        stream.next_sample = min(first, stream.start_sample)
        self._stream, self._session_start, self._ended_at = stream, at, None
        self._record()

    def _record(self) -> None:
        speech = self.base.speech
        self.stream.record(
            float(self.info["time"]),
            float(self.info["a"]),
            speech.path,
            speech.done,
            speech.pause_lengths,
        )

    def _step(self) -> None:
        obs, _, terminated, truncated, info = self.env.step(self.policy.act(self._obs))
        self._obs, self.info = obs, info
        self._record()
        if self.record:
            speech, f = self.base.speech, self.base.motion.f_user
            said = "" if speech.phrase is None or speech.in_pause else speech.phrase
            self.rows.append(
                (
                    self.sessions,
                    info["time"],
                    info["p"],
                    info["a"],
                    info["cooperation"],
                    info["em"],
                    float(f[0]),
                    float(f[1]),
                    float(f[2]),
                    said,
                )
            )
        if terminated or truncated:
            self.sessions += 1
            am = info.get("am")
            self.ams.append(float(am) if am is not None else math.nan)
            self._ended_at = self._session_start + float(info["time"])
            self.hooks.session_end(self, info)

    def _fill_audio(self, now_s: float) -> int:
        """Render what the stream can give into the ring; returns samples written."""
        free = self.ring.free()
        if free < BLOCK:
            return 0
        y = self.stream.render(now_s - self._session_start, free)
        return self.ring.write(y)

    def run(self, seconds: float | None = None) -> LoopReport:
        """Run until ``seconds`` of simulated time (None: until the hooks stop it)."""
        starved_before = 0
        self._new_session(0.0)
        ticks = late = 0
        max_lag = 0.0
        audio = 0
        started = False
        next_step = 0.0
        next_frame = 0.0
        t0 = time.monotonic()
        try:
            while (seconds is None or next_step < seconds - 1e-9) and self.hooks.running():
                now = time.monotonic() - t0
                if now >= next_step:
                    lag = now - next_step
                    max_lag = max(max_lag, lag)
                    if self._ended_at is None:
                        self._step()
                        ticks += self.base.ticks_per_step
                        if lag > TICK:
                            late += self.base.ticks_per_step
                    elif next_step >= self._ended_at + self.rest:
                        starved_before += self.stream.starved
                        self._new_session(next_step)
                    next_step += self.step_dt
                    continue
                audio += self._fill_audio(next_step)
                if not started and len(self.ring) >= self.prefill * self.sr:
                    self.sink.start()
                    started = True
                if now >= next_frame:
                    self.hooks.frame(self)
                    next_frame = now + 1.0 / 60.0
                    continue
                remaining = next_step - (time.monotonic() - t0)
                if remaining > 0:
                    time.sleep(min(remaining, 0.001))
            wall = time.monotonic() - t0
        finally:
            self.sink.stop()
        return LoopReport(
            wall_s=wall,
            sim_s=next_step,
            ticks=ticks,
            late_ticks=late,
            max_lag_ms=1e3 * max_lag,
            underruns=self.ring.underruns,
            missing_ms=1e3 * self.ring.missing / self.sr,
            device_xruns=self.sink.xruns,
            starved=starved_before + self.stream.starved,
            sessions=self.sessions,
            audio_s=audio / self.sr,
            ams=tuple(self.ams),
        )
