"""Variable-rate phase vocoder with phase locking, for live (block) and offline rendering.

The speech of the robot is played at an *audio pace* ``a`` that changes over time (``a = 1.2``
plays the content 20 % faster, so it lasts 1/1.2 as long). :class:`VariableRateVocoder`
time-scales mono audio with a short-time Fourier transform while keeping its pitch:

* **fixed synthesis hop** ``hop``; the analysis position in the content advances by about
  ``a * hop`` per output frame, at fractional positions (the analysis window is centred on the
  position rounded to the nearest sample, so no magnitude interpolation is needed);
* **instantaneous frequency** from the derivative-window (reassignment) estimate
  ``omega = omega_k - Im(X_dh / X_h)`` (rad/sample), exact for a stationary sinusoid and free of
  phase unwrapping; a peak's phase advances by ``hop`` times the mean of its frequency in the
  previous and the current frame (trapezoid rule);
* **phase locking** (Laroche & Dolson 1999): the peaks of the magnitude spectrum (bins larger
  than their two neighbours on each side) are propagated with peak tracking (a peak continues
  the phase of the previous frame's peak whose region held its bin, "scaled" locking with
  ``beta = 1``), and every bin of a peak's region of influence (split half-way between peaks)
  is rotated by its peak's phase rotation, which keeps the analysed phase offsets within the
  region (identity locking). Phases are zero-phase (referred to the frame centre). A peak more
  than 12 dB louder than its source (an onset, or a frame after silence) restarts from its
  analysed phase, which keeps attacks crisp and keeps onset errors from persisting;
* **overlap-add** with Hann analysis and synthesis windows, normalised per output sample by the
  accumulated sum of the window products (exact whatever the hops and window length).

The frames a pull commits are rendered by one compiled call
(:func:`langenv.speech.vocoder_kernels.render_pull`); this class keeps the timing.

Timing. Output sample ``j`` is played at pace ``a_j`` (the pace of the :meth:`pull` that
emitted it) and the content consumed is ``tau(j) = sum_{i<j} a_i`` samples, summed exactly
(integers, paces rounded to multiples of 2**-40). The output ends at the first sample ``T`` with
``tau(T) >= len(content)``, so ``integral_0^T a dt = len(y) / sr`` to within one sample. The
frame centred on output sample ``o`` is analysed at content position ``tau(s) + a_s * n_fft / 2``
where ``s = o - n_fft / 2`` is the first output sample it touches: the pace is known only up to
the sample being emitted, so it is extrapolated over the half frame, and the next frames absorb
the difference; the advance per frame is kept within ``[0.5, 2] * a * hop``, so a sudden change
of pace never moves the content backwards. Since every quantity depends only on the per-sample
pace, the output does not depend on how it is split into pulls: a sound card pulling small blocks
and an offline render of the same ``a(t)`` give the same samples.

Example::

    voc = VariableRateVocoder(22050)
    voc.push(clip)                       # content at base pace, float32 mono
    voc.finish()
    while not voc.done:
        out = voc.pull(256, a=current_pace())
"""

from __future__ import annotations

import math
from typing import Literal

import numpy as np

from langenv.errors import ActionError, ConfigError
from langenv.speech import vocoder_kernels as _kernels

__all__ = ["VariableRateVocoder", "periodic_hann", "time_stretch"]

#: Per-frame content advance is clamped to ``[_MIN_ADVANCE, _MAX_ADVANCE] * a * hop``.
_MIN_ADVANCE = 0.5
_MAX_ADVANCE = 2.0
#: A peak whose magnitude exceeds this times its source peak's restarts from its analysed phase.
_ONSET_RATIO = 4.0
#: Instantaneous frequencies are kept within this many bins of their bin (Hann main lobe).
_MAX_BIN_OFFSET = 2.0
#: Content buffer prefix (samples) that may be dropped before it is actually trimmed.
_TRIM_SLACK = 1 << 15
#: Paces are rounded to multiples of 2**-_PACE_BITS so that content time is summed exactly.
_PACE_BITS = 40
_PACE_ONE = 1 << _PACE_BITS


def _check_pace(a: float, name: str = "a") -> float:
    """Return ``a`` as a float after checking that it is finite and positive."""
    try:
        value = float(a)
    except (TypeError, ValueError) as exc:
        raise ActionError(f"{name} must be a positive finite number, got {a!r}") from exc
    if not math.isfinite(value) or value <= 0.0:
        raise ActionError(f"{name} must be a positive finite number, got {a!r}")
    return value


class VariableRateVocoder:
    """Pitch-preserving, phase-locked time-scaling at a pace that may change between pulls.

    Content is appended with :meth:`push` (mono, at base pace) and the stretched audio is read
    with :meth:`pull`, which may be called with a different pace every time; state (phases,
    content read position, overlap-add tail) is carried between pulls, so block boundaries are
    inaudible and the samples do not depend on the block sizes. A pull returns fewer samples than
    asked only when the content pushed so far does not reach far enough (it needs about
    ``(a + 1) * n_fft / 2`` samples beyond the content being played) or at the end of the
    content after :meth:`finish`.

    Attributes:
        content_time: Seconds of content consumed by the output so far (base pace).
        output_time: Seconds of output emitted so far.
        done: Content finished, fully consumed and the output fully emitted.

    Args:
        sr: Sample rate (Hz) of content and output.
        n_fft: Frame length (samples), even, at least 16 (1024 = 46 ms at 22.05 kHz).
        hop: Synthesis hop (samples), in ``[1, n_fft // 2]``; ``n_fft // 4`` is the usual choice.
        phase_lock: Lock the phases of each peak's region of influence (Laroche & Dolson); when
            false every bin's phase is propagated on its own (the classic phase vocoder, kept as
            a reference).

    Raises:
        ConfigError: If an argument is out of range (the message names it).
    """

    def __init__(
        self, sr: int, *, n_fft: int = 1024, hop: int = 256, phase_lock: bool = True
    ) -> None:
        if isinstance(sr, bool) or not isinstance(sr, int | np.integer) or sr <= 0:
            raise ConfigError(f"sr must be a positive integer (Hz), got {sr!r}")
        if (
            isinstance(n_fft, bool)
            or not isinstance(n_fft, int | np.integer)
            or n_fft < 16
            or n_fft % 2
        ):
            raise ConfigError(f"n_fft must be an even integer >= 16, got {n_fft!r}")
        if (
            isinstance(hop, bool)
            or not isinstance(hop, int | np.integer)
            or not 1 <= hop <= n_fft // 2
        ):
            raise ConfigError(
                f"hop must be an integer in [1, n_fft // 2 = {n_fft // 2}], got {hop!r}"
            )
        self.sr = int(sr)
        self.n_fft = int(n_fft)
        self.hop = int(hop)
        self.phase_lock = bool(phase_lock)

        n = self.n_fft
        self._half = n // 2
        self._n_bins = n // 2 + 1
        self._window = periodic_hann(n)
        self._fft = _kernels.frame_tables(n)
        # bin centre frequencies (rad/sample)
        self._omega_bin = 2.0 * np.pi * np.arange(self._n_bins) / n
        max_dw = _MAX_BIN_OFFSET * 2.0 * np.pi / n
        self._prm = np.array([self.hop, max_dw, _ONSET_RATIO], dtype=np.float64)
        # First frame whose span [m*hop - n/2, m*hop + n/2) reaches output sample 0.
        m0 = -(self._half // self.hop)
        while m0 * self.hop + self._half <= 0:
            m0 += 1
        self._first_frame = m0
        self._reset_state()

    # ------------------------------------------------------------------ state
    def _reset_state(self) -> None:
        self._buf = np.zeros(0, dtype=np.float32)  # content samples [buf_start, buf_start + len)
        self._buf_start = 0
        self._pushed = 0  # content samples pushed so far
        self._finished = False
        # Content consumed by the emitted output, exact, in units of 2**-_PACE_BITS samples.
        self._tau = 0
        self._out_pos = 0  # output samples emitted so far
        self._next_frame = self._first_frame
        self._prev_center: float | None = None  # content centre of the last synthesized frame
        # Overlap-add accumulators for output samples [out_pos, out_pos + len).
        self._acc = np.zeros(2 * self.n_fft, dtype=np.float64)
        self._wsum = np.zeros(2 * self.n_fft, dtype=np.float64)
        self._used = 0  # acc/wsum[used:] are zeros (no frame reached there yet)
        # Phase state of the last frame (see langenv.speech.vocoder_kernels): locked, phase
        # (rad), frequency (rad/sample) and magnitude of each of its peaks and the peak owning
        # each bin; free, phase and frequency of every bin. count[0] = -1: no previous frame.
        self._state = np.zeros((_kernels.N_STATE, self._n_bins), dtype=np.float64)
        self._count = np.full(1, -1, dtype=np.int64)

    # ------------------------------------------------------------------ public API
    @property
    def content_time(self) -> float:
        """Seconds of content consumed by the output emitted so far (base pace)."""
        return min(self._tau, self._pushed << _PACE_BITS) / _PACE_ONE / self.sr

    @property
    def output_time(self) -> float:
        """Seconds of output emitted so far."""
        return self._out_pos / self.sr

    @property
    def finished(self) -> bool:
        """Whether :meth:`finish` has been called."""
        return self._finished

    @property
    def done(self) -> bool:
        """Whether the content is finished, fully consumed and the output fully emitted."""
        return self._finished and self._tau >= self._pushed << _PACE_BITS

    def push(self, y: np.ndarray) -> None:
        """Append content at base pace.

        Args:
            y: Mono audio, shape ``(n,)``, finite; converted to float32.

        Raises:
            ConfigError: If ``y`` is not a finite 1-D array or :meth:`finish` was called.
        """
        if self._finished:
            raise ConfigError("push() called after finish(): no more content can be added (y)")
        arr = np.asarray(y)
        if arr.ndim != 1:
            raise ConfigError(f"y must be mono audio of shape (n,), got shape {arr.shape}")
        if arr.size and arr.dtype.kind not in "biuf":
            raise ConfigError(f"y must be real-valued audio, got dtype {arr.dtype}")
        arr = arr.astype(np.float32, copy=False)
        if not np.all(np.isfinite(arr)):
            raise ConfigError("y must be finite (found NaN or inf samples)")
        if arr.size:
            self._buf = np.concatenate([self._buf, arr])
            self._pushed += arr.size

    def finish(self) -> None:
        """Declare that no more content will be pushed (the output then ends with the content)."""
        self._finished = True

    def resume(self) -> None:
        """Take content again after :meth:`finish` (a speech that goes on after its end): what
        is pushed next follows the content pushed so far; push a frame of silence first, so
        that no frame already emitted overlaps the new content. Once the output has emitted
        all the content (:attr:`done`), what the last frames left in the overlap-add is dropped
        and the phase starts afresh; before, nothing is dropped."""
        if self.done:
            self._acc[:] = 0.0
            self._wsum[:] = 0.0
            self._used = 0
            self._count[0] = -1
        self._finished = False

    def pull(self, n: int, a: float) -> np.ndarray:
        """Render up to ``n`` output samples at pace ``a``.

        Args:
            n: Number of samples wanted (>= 0).
            a: Audio pace for these samples (> 0, finite): content seconds per output second.

        Returns:
            Output audio, float32, shape ``(k,)`` with ``k <= n``; ``k < n`` only when the
            pushed content does not reach far enough yet or the content ends.

        Raises:
            ActionError: If ``a`` is not a positive finite number.
            ConfigError: If ``n`` is negative or not an integer.
        """
        if type(a) is not float or not 0.0 < a < math.inf:  # fast path for a plain float
            a = _check_pace(a)
        bad_type = type(n) is not int and (
            isinstance(n, bool) or not isinstance(n, int | np.integer)
        )
        if bad_type or n < 0:
            raise ConfigError(f"n must be a non-negative integer, got {n!r}")
        n = int(n)
        a_q = max(1, round(a * _PACE_ONE))  # pace on an exact binary grid
        if self._finished:
            remaining = (self._pushed << _PACE_BITS) - self._tau
            if remaining <= 0:
                return np.zeros(0, dtype=np.float32)
            n = min(n, -(-remaining // a_q))
        if n == 0:
            return np.zeros(0, dtype=np.float32)
        out = self._render(self._out_pos + n, a_q)
        k = out.size
        if k:
            self._out_pos += k
            self._tau += a_q * k
            self._trim_content()
        return out

    # ------------------------------------------------------------------ internals
    def _schedule(self, end: int, a_q: int) -> tuple[list[int], int]:
        """Analysis positions of the frames to render now, and how far the output is complete.

        Args:
            end: Output sample (exclusive) the caller wants to emit up to.
            a_q: Pace of the samples being emitted, in units of 2**-_PACE_BITS.

        Returns:
            ``(centres, ready)``: the content sample at the centre of each frame to commit (frames
            ``_next_frame, _next_frame + 1, ...``), and the output sample up to which (exclusive)
            the output is complete: ``end``, or the first sample of the first frame the pushed
            content does not cover yet. Updates ``_prev_center``.
        """
        hop, half, out_pos, tau = self.hop, self._half, self._out_pos, self._tau
        a = a_q / _PACE_ONE
        lo_step, hi_step = _MIN_ADVANCE * a * hop, _MAX_ADVANCE * a * hop
        limit = math.inf if self._finished else self._pushed - half
        centres: list[int] = []
        frame_c: list[float] = []
        m = self._next_frame
        prev_c = self._prev_center
        ready = end
        while m * hop - half < end:
            start = m * hop - half
            c = (tau + a_q * (start - out_pos + half)) / _PACE_ONE
            if prev_c is not None:
                c = min(max(c, prev_c + lo_step), prev_c + hi_step)
            p = math.floor(c + 0.5)
            if p > limit:
                ready = max(start, out_pos)
                break
            centres.append(p)
            frame_c.append(c)
            prev_c = c
            m += 1
        # Only frames whose first output sample is emitted now are committed: the pace of that
        # sample fixes their analysis position (pre-roll frames wait for output sample 0).
        n_commit = len(centres)
        while n_commit and max((self._next_frame + n_commit - 1) * hop - half, out_pos) >= ready:
            n_commit -= 1
        if n_commit:
            self._prev_center = frame_c[n_commit - 1]
        return centres[:n_commit], ready

    def _render(self, end: int, a_q: int) -> np.ndarray:
        """Render every frame starting before output sample ``end`` that the content allows, and
        emit the output samples that are complete (one compiled call).

        Args:
            end: Output sample (exclusive) the caller wants to emit up to.
            a_q: Pace of the samples being emitted, in units of 2**-_PACE_BITS.

        Returns:
            The emitted samples (float32), from output sample ``_out_pos`` on.
        """
        centres, ready = self._schedule(end, a_q)
        n, hop = self.n_fft, self.hop
        first = self._next_frame
        k = max(ready - self._out_pos, 0)
        first_start = first * hop - self._half - self._out_pos
        used = max(self._used, first_start + (len(centres) - 1) * hop + n, k)
        if used > self._acc.size:
            grow = used - self._acc.size + 4 * n
            self._acc = np.concatenate([self._acc, np.zeros(grow)])
            self._wsum = np.concatenate([self._wsum, np.zeros(grow)])
        self._next_frame += len(centres)
        self._used = used - k
        return _kernels.render_pull(
            self._buf,
            self._buf_start,
            np.array(centres, dtype=np.int64),
            first_start,
            self._window,
            *self._fft,
            self._omega_bin,
            self._prm,
            self.phase_lock,
            self._state,
            self._count,
            self._acc,
            self._wsum,
            k,
            used,
        )

    def _trim_content(self) -> None:
        """Drop content that no future frame can read (amortised)."""
        if self._prev_center is None:
            return
        keep_from = math.floor(self._prev_center) - self._half - 2
        drop = keep_from - self._buf_start
        if drop > _TRIM_SLACK and drop > self._buf.size // 2:
            drop = min(drop, self._buf.size)
            self._buf = self._buf[drop:].copy()
            self._buf_start += drop


def time_stretch(
    y: np.ndarray,
    sr: int,
    t: np.ndarray,
    a: np.ndarray,
    *,
    n_fft: int = 1024,
    hop: int = 256,
    phase_lock: bool = True,
    block: int = 512,
    interp: Literal["linear", "previous"] = "linear",
) -> np.ndarray:
    """Render ``y`` at a time-varying pace ``a(t)`` offline (push all, finish, pull in blocks).

    The pace is a function of output time: ``interp="linear"`` interpolates the samples
    ``(t, a)`` linearly and evaluates them at the middle of each block of ``block`` output
    samples; ``interp="previous"`` holds each value from output sample ``round(t[i] * sr)`` until
    the next one (blocks are split there, so a trace recorded from live pulls is reproduced
    sample for sample). Outside ``[t[0], t[-1]]`` the end values are held. The output lasts
    ``T`` with ``integral_0^T a(t) dt = len(y) / sr`` (to one sample).

    Args:
        y: Mono content, shape ``(n,)``.
        sr: Sample rate (Hz).
        t: Times of the pace samples (s), shape ``(m,)``, strictly increasing, ``m >= 1``.
        a: Pace at those times, shape ``(m,)``, each positive and finite.
        n_fft: Frame length (samples), see :class:`VariableRateVocoder`.
        hop: Synthesis hop (samples).
        phase_lock: Use phase locking.
        block: Output samples per pull (> 0).
        interp: ``"linear"`` or ``"previous"`` (sample and hold).

    Returns:
        The stretched audio, float32, shape ``(T * sr,)``.

    Raises:
        ActionError: If a value of ``a`` is not positive and finite.
        ConfigError: If ``t``/``a`` shapes or ``t`` ordering, ``block`` or ``interp`` are invalid.
    """
    try:
        a_arr = np.atleast_1d(np.asarray(a, dtype=np.float64))
    except (TypeError, ValueError) as exc:
        raise ActionError(f"a must be an array of positive finite paces, got {a!r}") from exc
    try:
        t_arr = np.atleast_1d(np.asarray(t, dtype=np.float64))
    except (TypeError, ValueError) as exc:
        raise ConfigError(f"t must be an array of times (s), got {t!r}") from exc
    if t_arr.ndim != 1 or a_arr.ndim != 1:
        raise ConfigError("t and a must be 1-D arrays of pace samples (s, pace)")
    if a_arr.size == 0:
        raise ActionError("a must contain at least one pace value")
    if t_arr.shape != a_arr.shape:
        raise ConfigError(f"t and a must have the same shape, got {t_arr.shape} and {a_arr.shape}")
    if not np.all(np.isfinite(a_arr)) or np.any(a_arr <= 0.0):
        raise ActionError("a must contain only positive finite pace values")
    if not np.all(np.isfinite(t_arr)) or np.any(np.diff(t_arr) <= 0.0):
        raise ConfigError("t must be finite and strictly increasing (s)")
    if isinstance(block, bool) or not isinstance(block, int | np.integer) or block <= 0:
        raise ConfigError(f"block must be a positive integer (samples), got {block!r}")
    if interp not in ("linear", "previous"):
        raise ConfigError(f"interp must be 'linear' or 'previous', got {interp!r}")

    voc = VariableRateVocoder(sr, n_fft=n_fft, hop=hop, phase_lock=phase_lock)
    voc.push(np.asarray(y))
    voc.finish()
    breaks = np.rint(t_arr * sr).astype(np.int64)
    chunks: list[np.ndarray] = []
    pos = 0
    while not voc.done:
        if interp == "previous":
            i = int(np.searchsorted(breaks, pos, side="right")) - 1
            pace = float(a_arr[max(i, 0)])
            size = block
            if i + 1 < breaks.size:
                size = min(size, int(breaks[i + 1]) - pos)
        else:
            size = block
            pace = float(np.interp((pos + 0.5 * size) / sr, t_arr, a_arr))
        chunk = voc.pull(size, pace)
        if chunk.size == 0:  # cannot happen once finished; guards against an endless loop
            break
        chunks.append(chunk)
        pos += chunk.size
    return np.concatenate(chunks) if chunks else np.zeros(0, dtype=np.float32)


def periodic_hann(n: int) -> np.ndarray:
    """The periodic ("DFT-even") Hann window of ``n`` samples, float64 ``(n,)``.

    ``scipy.signal.get_window("hann", n)`` (and so librosa's) to the bit: the same operations in
    the same order (a generalised cosine window over ``n + 1`` points, the last dropped), without
    importing ``scipy.signal`` or ``librosa.filters`` (seconds per process).
    """
    if n <= 1:  # scipy's guard: no taper on 0 or 1 samples
        return np.ones(max(n, 0), dtype=np.float64)
    fac = np.linspace(-np.pi, np.pi, n + 1, dtype=np.float64)
    w = np.zeros(n + 1, dtype=np.float64)
    for k, a in enumerate(np.asarray([0.5, 0.5])):
        w += a * np.cos(k * fac)
    return w[:-1]
