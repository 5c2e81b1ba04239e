"""Compiled frame kernel of :class:`~langenv.speech.vocoder.VariableRateVocoder` (numba).

One call renders a batch of frames (the frames one :meth:`~VariableRateVocoder.pull` commits):
it gathers each frame's content, transforms it, sets the synthesis phases (phase-locked or free)
and overlap-adds the result, so a pull costs one call into compiled code instead of a dozen NumPy
calls per frame.

Transforms: :func:`fft` is an iterative radix-2 FFT (length a power of two, twiddles from a
table; a direct ``O(n^2)`` DFT for other lengths, so that any even ``n_fft`` works). A frame's
real transform is one complex transform of length ``n / 2`` (even and odd samples as real and
imaginary parts); the Hann window and its time derivative are applied in the frequency domain
(``X_h(k) = X(k) / 2 - (X(k - 1) + X(k + 1)) / 4``, ``X_dh(k) = (pi / n) (X(k - 1) - X(k + 1)) /
(2 i)``); the inverse real transform is again one complex transform of length ``n / 2``.
The rest repeats the NumPy implementation it replaced operation for operation (NumPy's complex
division, ``remainder``, ``exp`` of an imaginary number as ``cos + i sin``), so the output differs
from it only by the transforms' rounding (relative 1e-15: a few float32 ulps, see
``tests/test_vocoder.py::test_matches_numpy_reference``).

State between batches (``state``, float64 rows of ``K = n_fft // 2 + 1``): phase, frequency and
magnitude of the last frame's peaks (locked) or of every bin (free), the last frame's region of
each bin, and ``count[0]``: the number of peaks of the last frame (``-1``: no previous frame, or a
previous frame without peaks).
"""

from __future__ import annotations

import math

import numpy as np

from langenv.kernels import jit

__all__ = ["emit", "fft", "fft_tables", "frame_tables", "render_frames", "render_pull"]

#: Rows of the ``state`` array.
S_PHASE, S_OMEGA, S_MAG, S_REGION = 0, 1, 2, 3
N_STATE = 4


def fft_tables(n: int) -> tuple[np.ndarray, np.ndarray]:
    """Tables of :func:`fft` for length ``n``: bit-reversal permutation and twiddles.

    For a power of two, ``rev`` is the bit-reversal permutation and ``tw`` holds, for each stage of
    half-length ``h = 1, 2, 4, ...``, ``exp(-i pi k / h)`` for ``k < h`` (at ``tw[h - 1 + k]``), as
    rows (real, imaginary), shape (2, n - 1). For any other length ``rev`` is empty and ``tw``
    holds ``exp(-2 pi i k / n)``, ``k < n``, shape (2, n), for the direct DFT.
    """
    if n & (n - 1) == 0:
        bits = n.bit_length() - 1
        idx = np.arange(n)
        rev = np.zeros(n, dtype=np.int64)
        for b in range(bits):
            rev |= ((idx >> b) & 1) << (bits - 1 - b)
        w = np.concatenate(
            [np.ones(0, dtype=np.complex128)]
            + [np.exp(-1j * np.pi * np.arange(h) / h) for h in (1 << s for s in range(bits))]
        )
    else:
        rev = np.zeros(0, dtype=np.int64)
        w = np.exp(-2j * np.pi * np.arange(n) / n)
    return rev, np.ascontiguousarray(np.stack([w.real, w.imag]))


def frame_tables(n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(rev, tw, twn)`` of :func:`render_frames` for frames of ``n`` samples (even): the
    :func:`fft_tables` of ``n / 2`` and ``exp(-2 pi i k / n)``, ``k <= n / 2``, as rows (real,
    imaginary)."""
    rev, tw = fft_tables(n // 2)
    w = np.exp(-2j * np.pi * np.arange(n // 2 + 1) / n)
    return rev, tw, np.ascontiguousarray(np.stack([w.real, w.imag]))


@jit
def fft(xr: np.ndarray, xi: np.ndarray, rev: np.ndarray, tw: np.ndarray) -> None:
    """In-place forward DFT of ``xr + i xi`` (length ``n``), tables from :func:`fft_tables`.

    Radix 2 (decimation in time) for a power of two, the first two stages as one radix-4 pass
    (twiddles 1 and -i exactly), else the direct ``O(n^2)`` sum.
    """
    if rev.size > 0:  # radix 2: into bit-reversed order first
        for i in range(xr.size):
            j = rev[i]
            if j > i:
                xr[i], xr[j] = xr[j], xr[i]
                xi[i], xi[j] = xi[j], xi[i]
    _transform_placed(xr, xi, rev, tw)


@jit
def _transform_placed(xr: np.ndarray, xi: np.ndarray, rev: np.ndarray, tw: np.ndarray) -> None:
    """The rest of :func:`fft` on input already placed: in bit-reversed order for a radix-2
    length (non-empty ``rev``), in natural order for the direct sum."""
    if rev.size > 0:
        _butterflies(xr, xi, tw)
    else:
        _dft(xr, xi, tw)


@jit
def _butterflies(xr: np.ndarray, xi: np.ndarray, tw: np.ndarray) -> None:
    """The butterfly stages of :func:`fft` on input already in bit-reversed order (power of two
    lengths only)."""
    n = xr.size
    half = 1
    if n >= 4:
        for p in range(0, n, 4):
            ar, ai = xr[p] + xr[p + 1], xi[p] + xi[p + 1]
            br, bi = xr[p] - xr[p + 1], xi[p] - xi[p + 1]
            cr, ci = xr[p + 2] + xr[p + 3], xi[p + 2] + xi[p + 3]
            dr, di = xr[p + 2] - xr[p + 3], xi[p + 2] - xi[p + 3]
            xr[p], xi[p] = ar + cr, ai + ci
            xr[p + 2], xi[p + 2] = ar - cr, ai - ci
            xr[p + 1], xi[p + 1] = br + di, bi - dr  # b + (-i) d
            xr[p + 3], xi[p + 3] = br - di, bi + dr
        half = 4
    while 2 * half < n:  # two radix-2 stages per pass (half and 2 half): one pass over memory
        off1 = half - 1
        off2 = 2 * half - 1
        for start in range(0, n, 4 * half):
            for k in range(half):
                p0 = start + k
                p1 = p0 + half
                p2 = p1 + half
                p3 = p2 + half
                c, d = tw[0, off1 + k], tw[1, off1 + k]
                vr = xr[p1] * c - xi[p1] * d
                vi = xr[p1] * d + xi[p1] * c
                ar, ai = xr[p0] + vr, xi[p0] + vi
                br, bi = xr[p0] - vr, xi[p0] - vi
                vr = xr[p3] * c - xi[p3] * d
                vi = xr[p3] * d + xi[p3] * c
                cr, ci = xr[p2] + vr, xi[p2] + vi
                dr, di = xr[p2] - vr, xi[p2] - vi
                c, d = tw[0, off2 + k], tw[1, off2 + k]
                vr = cr * c - ci * d
                vi = cr * d + ci * c
                xr[p0], xi[p0] = ar + vr, ai + vi
                xr[p2], xi[p2] = ar - vr, ai - vi
                c, d = tw[0, off2 + half + k], tw[1, off2 + half + k]
                vr = dr * c - di * d
                vi = dr * d + di * c
                xr[p1], xi[p1] = br + vr, bi + vi
                xr[p3], xi[p3] = br - vr, bi - vi
        half *= 4
    if half < n:  # a last single stage
        off = half - 1
        for k in range(half):
            c, d = tw[0, off + k], tw[1, off + k]
            q = k + half
            vr = xr[q] * c - xi[q] * d
            vi = xr[q] * d + xi[q] * c
            ur, ui = xr[k], xi[k]
            xr[k], xi[k] = ur + vr, ui + vi
            xr[q], xi[q] = ur - vr, ui - vi


@jit
def _dft(xr: np.ndarray, xi: np.ndarray, tw: np.ndarray) -> None:
    n = xr.size
    yr = np.zeros(n)
    yi = np.zeros(n)
    for k in range(n):
        for j in range(n):
            m = (j * k) % n
            yr[k] += xr[j] * tw[0, m] - xi[j] * tw[1, m]
            yi[k] += xr[j] * tw[1, m] + xi[j] * tw[0, m]
    xr[:] = yr
    xi[:] = yi


@jit
def _analyse(
    buf: np.ndarray,
    lo: int,
    rev: np.ndarray,
    tw: np.ndarray,
    twn: np.ndarray,
    wr: np.ndarray,
    wi: np.ndarray,
    spec: np.ndarray,
    x_h: np.ndarray,
    x_dh: np.ndarray,
) -> None:
    """Spectra of ``buf[lo : lo + n]`` (zeros outside ``buf``) under the periodic Hann window and
    its time derivative, bins ``0..n/2``.

    One real transform of the frame (a complex transform of length ``n / 2``: even and odd samples
    as real and imaginary parts), then both windows in the frequency domain:
    ``X_h(k) = X(k) / 2 - (X(k - 1) + X(k + 1)) / 4`` and
    ``X_dh(k) = (pi / n) (X(k - 1) - X(k + 1)) / (2 i)``.
    """
    m = wr.size  # n / 2
    size = buf.size
    radix2 = rev.size > 0  # filled in bit-reversed order then (see _transform_placed)
    if lo >= 0 and lo + 2 * m <= size:
        for j in range(m):
            r = rev[j] if radix2 else j
            wr[r] = buf[lo + 2 * j]
            wi[r] = buf[lo + 2 * j + 1]
    else:  # the frame reaches before the start or past the end of the content: zeros there
        for j in range(m):
            i = lo + 2 * j
            r = rev[j] if radix2 else j
            wr[r] = float(buf[i]) if 0 <= i < size else 0.0
            wi[r] = float(buf[i + 1]) if 0 <= i + 1 < size else 0.0
    _transform_placed(wr, wi, rev, tw)
    for k in range(m + 1):
        a = k if k < m else 0
        c = m - k if k > 0 else 0
        cr, ci = wr[a], wi[a]
        dr, di = wr[c], -wi[c]  # conj(C(m - k))
        er, ei = 0.5 * (cr + dr), 0.5 * (ci + di)  # even samples' spectrum
        orr, oi = 0.5 * (ci - di), -0.5 * (cr - dr)  # odd samples' spectrum
        tr, ti = twn[0, k], twn[1, k]
        spec[k + 1] = complex(er + orr * tr - oi * ti, ei + orr * ti + oi * tr)
    spec[0] = spec[2].conjugate()  # X(-1)
    spec[m + 2] = spec[m].conjugate()  # X(n/2 + 1)
    scale = math.pi / (2 * m) / 2.0
    for k in range(m + 1):
        lft = spec[k]
        mid = spec[k + 1]
        rgt = spec[k + 2]
        x_h[k] = complex(
            0.5 * mid.real - 0.25 * (lft.real + rgt.real),
            0.5 * mid.imag - 0.25 * (lft.imag + rgt.imag),
        )
        x_dh[k] = complex(scale * (lft.imag - rgt.imag), -scale * (lft.real - rgt.real))


@jit
def _np_div_imag(ar: float, ai: float, br: float, bi: float) -> float:
    """``Im(a / b)`` as NumPy's complex division computes it (Smith's algorithm)."""
    if abs(br) >= abs(bi):
        if br == 0.0 and bi == 0.0:
            return ai / abs(br)
        rat = bi / br
        scl = 1.0 / (br + bi * rat)
        return (ai - ar * rat) * scl
    rat = br / bi
    scl = 1.0 / (bi + br * rat)
    return (ai * rat - ar) * scl


@jit
def _np_remainder(a: float, b: float) -> float:
    """``numpy.remainder(a, b)`` for ``b > 0`` (the sign of the divisor)."""
    mod = np.fmod(a, b)
    if mod != 0.0:
        if (b < 0.0) != (mod < 0.0):
            mod += b
    else:
        mod = math.copysign(0.0, b)
    return mod


@jit
def _clip(x: float, bound: float) -> float:
    return min(max(x, -bound), bound)


@jit
def _lock_frame(
    x_h: np.ndarray,
    x_dh: np.ndarray,
    prm: np.ndarray,
    omega_bin: np.ndarray,
    state: np.ndarray,
    count: np.ndarray,
    peaks: np.ndarray,
    work: np.ndarray,
    rot: np.ndarray,
    z: np.ndarray,
) -> None:
    """Phase-locked synthesis spectrum of one frame into ``z``; updates the peak state.

    ``peaks`` (int), ``work`` (4 rows) and ``rot`` (complex): scratch, at least ``x_h.size`` long.

    The sources' phases are those of the previous frame's peaks, wrapped to ``[0, 2 pi)`` at the
    end of a batch and not within one (as the NumPy implementation this repeats did).
    """
    hop, max_dw, onset = prm[0], prm[1], prm[2]
    n_bins = x_h.size
    power = work[0]  # peaks are found on the power (|X|^2, monotonic in |X|)
    for k in range(n_bins):
        xk = x_h[k]
        power[k] = xk.real * xk.real + xk.imag * xk.imag
    n_peaks = 0
    for k in range(2, n_bins - 2):
        m = power[k]
        if m > power[k - 1] and m > power[k - 2] and m >= power[k + 1] and m >= power[k + 2]:
            peaks[n_peaks] = k
            n_peaks += 1
    n_prev = count[0]
    if n_peaks == 0:  # silence: analysed phases kept, no source for the next frame
        z[:] = x_h
        count[0] = -1
        return
    new_phase = work[1]
    new_omega = work[2]
    new_mag = work[3]
    for j in range(n_peaks):
        k = peaks[j]
        xk = x_h[k]
        dk = x_dh[k]
        offset = _np_div_imag(dk.real, dk.imag, xk.real, xk.imag)
        omega = omega_bin[k] - _clip(offset, max_dw)
        src = -1 if n_prev < 0 else int(state[S_REGION, k])
        src_mag = 0.0 if src < 0 else state[S_MAG, src]
        mag = abs(xk)
        if mag > onset * src_mag:  # an onset, or no source: restart from the analysed phase
            phase = math.atan2(xk.imag, xk.real) + math.pi * (k % 2)
            rot[j] = 1.0
        else:  # rot = exp(i (phase - analysed phase)) = exp(i phase) conj(X) / |X| (-1)^k
            phase = state[S_PHASE, src] + (0.5 * hop) * (state[S_OMEGA, src] + omega)
            c, s = math.cos(phase), math.sin(phase)
            u = (1.0 if k % 2 == 0 else -1.0) / mag
            rot[j] = complex((c * xk.real + s * xk.imag) * u, (s * xk.real - c * xk.imag) * u)
        new_phase[j] = phase
        new_omega[j] = omega
        new_mag[j] = mag
    # Region of influence: bins up to half-way (rounded up) to the next peak.
    j = 0
    for k in range(n_bins):
        while j + 1 < n_peaks and k >= (peaks[j] + peaks[j + 1] + 1) // 2:
            j += 1
        r = rot[j]
        xk = x_h[k]
        z[k] = complex(xk.real * r.real - xk.imag * r.imag, xk.real * r.imag + xk.imag * r.real)
        state[S_REGION, k] = j
    for j in range(n_peaks):
        state[S_PHASE, j] = new_phase[j]
        state[S_OMEGA, j] = new_omega[j]
        state[S_MAG, j] = new_mag[j]
    count[0] = n_peaks


@jit
def _free_frame(
    x_h: np.ndarray,
    x_dh: np.ndarray,
    prm: np.ndarray,
    omega_bin: np.ndarray,
    state: np.ndarray,
    count: np.ndarray,
    z: np.ndarray,
) -> None:
    """Classic phase vocoder: every bin advances by ``hop`` times its mean frequency.

    ``state[S_PHASE]`` holds the running phase of the batch (not wrapped), ``state[S_OMEGA]`` the
    frequencies; the caller wraps the phases at the end of the batch.
    """
    hop, max_dw = prm[0], prm[1]
    for k in range(x_h.size):
        xk = x_h[k]
        dk = x_dh[k]
        power = xk.real * xk.real + xk.imag * xk.imag
        cross = dk.imag * xk.real - dk.real * xk.imag
        omega = omega_bin[k] - _clip(cross / max(power, 1e-30), max_dw)
        if count[0] < 0:
            phase = math.atan2(xk.imag, xk.real) + math.pi * (k % 2)
        else:
            phase = state[S_PHASE, k] + 0.5 * hop * (state[S_OMEGA, k] + omega)
        state[S_PHASE, k] = phase
        state[S_OMEGA, k] = omega
        m = abs(xk)
        d = (_np_remainder(phase + math.pi, 2.0 * math.pi) - math.pi) - math.pi * (k % 2)
        z[k] = complex(m * math.cos(d), m * math.sin(d))
    count[0] = 0


@jit
def _synthesize(
    z: np.ndarray,
    frame: np.ndarray,
    rev: np.ndarray,
    tw: np.ndarray,
    twn: np.ndarray,
    wr: np.ndarray,
    wi: np.ndarray,
) -> None:
    """Inverse real DFT of length ``n`` from bins ``0..n/2`` (the imaginary parts of bins 0 and
    ``n/2`` ignored, as ``numpy.fft.irfft`` does): one complex transform of length ``n/2``.

    ``twn``: ``exp(-2 pi i k / n)``, ``k <= n/2``, rows (real, imaginary).
    """
    m = wr.size  # n / 2
    radix2 = rev.size > 0
    for k in range(m):
        a = z[k]
        b = z[m - k]
        ar, ai = a.real, (0.0 if k == 0 else a.imag)
        br, bi = b.real, (0.0 if k == 0 else -b.imag)  # conj(Z(m - k)); Z(m) and Z(0) real
        er, ei = ar + br, ai + bi  # 2 * even part
        dr, di = ar - br, ai - bi  # 2 * odd part / twiddle
        orr = dr * twn[0, k] + di * twn[1, k]  # times exp(2 pi i k / n)
        oi = di * twn[0, k] - dr * twn[1, k]
        # C = E + i O, conjugated (the inverse through the forward transform), stored in
        # bit-reversed order (the FFT's first step)
        r = rev[k] if radix2 else k
        wr[r] = er - oi
        wi[r] = -(ei + orr)
    _transform_placed(wr, wi, rev, tw)
    scale = 1.0 / (2 * m)
    for j in range(m):
        frame[2 * j] = wr[j] * scale
        frame[2 * j + 1] = -wi[j] * scale


@jit
def render_frames(
    buf: np.ndarray,
    buf_start: int,
    centres: np.ndarray,
    first_start: int,
    window: np.ndarray,
    rev: np.ndarray,
    tw: np.ndarray,
    twn: np.ndarray,
    omega_bin: np.ndarray,
    prm: np.ndarray,
    lock: bool,
    state: np.ndarray,
    count: np.ndarray,
    acc: np.ndarray,
    wsum: np.ndarray,
) -> None:
    """Analyse at ``centres``, set the synthesis phases, overlap-add into ``acc`` and ``wsum``.

    Args:
        buf: Content samples from ``buf_start`` on (float32).
        buf_start: Content index of ``buf[0]``.
        centres: Content sample at the centre of each frame's window, shape (F,).
        first_start: Index in ``acc`` of the first frame's first sample (may be negative: the
            part before 0 is dropped); frame ``i`` starts ``i * hop`` later.
        window: Periodic Hann window (synthesis), shape (n,).
        rev, tw, twn: :func:`frame_tables` of ``n``.
        omega_bin: Bin centre frequencies (rad/sample), shape (K,).
        prm: ``(hop, max bin offset (rad/sample), onset ratio)``.
        lock: Phase locking (else the classic vocoder).
        state: Phase state, shape (N_STATE, K), updated.
        count: ``count[0]``, see the module docstring, updated.
        acc, wsum: Overlap-add accumulators, long enough for the batch, updated.
    """
    n = window.size
    n_bins = n // 2 + 1
    hop = int(prm[0])
    wr = np.empty(n // 2)
    wi = np.empty(n // 2)
    spec = np.empty(n // 2 + 3, dtype=np.complex128)
    x_h = np.empty(n_bins, dtype=np.complex128)
    x_dh = np.empty(n_bins, dtype=np.complex128)
    z = np.empty(n_bins, dtype=np.complex128)
    frame = np.empty(n)
    peaks = np.empty(n_bins, dtype=np.int64)
    work = np.empty((4, n_bins))
    rot = np.empty(n_bins, dtype=np.complex128)
    half = n // 2
    for i in range(centres.size):
        _analyse(buf, centres[i] - half - buf_start, rev, tw, twn, wr, wi, spec, x_h, x_dh)
        if lock:
            _lock_frame(x_h, x_dh, prm, omega_bin, state, count, peaks, work, rot, z)
        else:
            _free_frame(x_h, x_dh, prm, omega_bin, state, count, z)
        _synthesize(z, frame, rev, tw, twn, wr, wi)
        lo = first_start + i * hop
        for j in range(max(0, -lo), n):
            w = window[j]
            acc[lo + j] += frame[j] * w
            wsum[lo + j] += w * w
    # Sources of the next batch: phases wrapped (locked: to [0, 2 pi); free: to [-pi, pi)).
    if lock:
        for j in range(max(count[0], 0)):
            state[S_PHASE, j] = _np_remainder(state[S_PHASE, j], 2.0 * math.pi)
    else:
        for k in range(n_bins):
            state[S_PHASE, k] = _np_remainder(state[S_PHASE, k] + math.pi, 2.0 * math.pi) - math.pi


@jit
def render_pull(
    buf: np.ndarray,
    buf_start: int,
    centres: np.ndarray,
    first_start: int,
    window: np.ndarray,
    rev: np.ndarray,
    tw: np.ndarray,
    twn: np.ndarray,
    omega_bin: np.ndarray,
    prm: np.ndarray,
    lock: bool,
    state: np.ndarray,
    count: np.ndarray,
    acc: np.ndarray,
    wsum: np.ndarray,
    k: int,
    used: int,
) -> np.ndarray:
    """One pull in one call: :func:`render_frames`, then the first ``k`` output samples
    (:func:`emit`), then ``acc[:used]`` and ``wsum[:used]`` shifted left by ``k`` (zeros enter
    behind), so that index 0 is again the first sample not emitted yet. ``used``: the end of the
    samples any frame has touched (``k <= used <= acc.size``; zeros beyond).

    Returns:
        The emitted samples, float32, shape (k,).
    """
    render_frames(
        buf,
        buf_start,
        centres,
        first_start,
        window,
        rev,
        tw,
        twn,
        omega_bin,
        prm,
        lock,
        state,
        count,
        acc,
        wsum,
    )
    out = emit(acc, wsum, k)
    for j in range(used - k):
        acc[j] = acc[j + k]
        wsum[j] = wsum[j + k]
    for j in range(max(used - k, 0), used):
        acc[j] = 0.0
        wsum[j] = 0.0
    return out


@jit
def emit(acc: np.ndarray, wsum: np.ndarray, k: int) -> np.ndarray:
    """The first ``k`` finished output samples: ``acc / wsum`` (0 where ``wsum <= 1e-12``),
    float32, shape (k,)."""
    out = np.zeros(k, dtype=np.float32)
    for j in range(k):
        if wsum[j] > 1e-12:
            out[j] = acc[j] / wsum[j]
    return out
