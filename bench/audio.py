"""Throughput of the variable-rate phase vocoder (``audio_rtf``).

``measure_audio_rtf`` renders speech-like audio at 22.05 kHz through
:class:`langenv.speech.vocoder.VariableRateVocoder` the way the session renderer does (content
pushed once, 512-sample pulls, the pace changing every pull) and returns the seconds of audio
rendered per second of wall time. ``langctrl bench-audio`` prints it.
"""

from __future__ import annotations

import time
from typing import Literal

import numpy as np
import scipy.signal

__all__ = ["measure_audio_rtf", "speech_like_signal"]

SR = 22050
_VOWELS = np.array([[730, 1090, 2440], [270, 2290, 3010], [530, 1840, 2480], [570, 840, 2410]])


def speech_like_signal(
    seconds: float, rng: np.random.Generator, sr: int = SR, *, bursts: bool = True
) -> np.ndarray:
    """Synthetic speech: a glottal pulse train through moving formants, in syllables.

    The pitch glides between about 120 and 190 Hz, the three formants move between four vowels
    every 0.22 s syllable, and every third syllable ends in a noise burst (a consonant).

    Args:
        seconds: Duration (s), > 0.
        rng: Source of the vowel sequence and of the noise.
        sr: Sample rate (Hz).
        bursts: Whether the syllables' noise bursts are there (False: voiced only; the noise is
            drawn either way).

    Returns:
        Mono float32 audio, shape ``(round(seconds * sr),)``, peak 0.5.
    """
    n = round(seconds * sr)
    t = np.arange(n) / sr
    f0 = 155.0 + 30.0 * np.sin(2 * np.pi * 0.7 * t) + 8.0 * np.sin(2 * np.pi * 4.5 * t)
    pulses = np.diff(np.floor(np.cumsum(f0) / sr), prepend=0.0)
    source = scipy.signal.lfilter([1.0], [1.0, -0.97], pulses)
    syllable = 0.22
    index = (t / syllable).astype(int)
    choice = rng.integers(0, len(_VOWELS), size=int(index.max(initial=0)) + 2)
    y = np.zeros(n)
    state = [np.zeros(2) for _ in range(3)]
    for s in range(0, n, 256):
        e = min(n, s + 256)
        frac = (t[s] % syllable) / syllable
        formants = (1 - frac) * _VOWELS[choice[index[s]]] + frac * _VOWELS[choice[index[s] + 1]]
        for j, (fc, bw) in enumerate(zip(formants, (80.0, 100.0, 120.0), strict=True)):
            r = np.exp(-np.pi * bw / sr)
            den = [1.0, -2 * r * np.cos(2 * np.pi * fc / sr), r * r]
            out, state[j] = scipy.signal.lfilter([1 - r], den, source[s:e], zi=state[j])
            y[s:e] += out / (j + 1)
    envelope = np.clip(1.3 * np.sin(np.pi * (t % syllable) / syllable), 0.0, 1.0) ** 0.7
    noisy = (np.sin(np.pi * (t % (3 * syllable)) / (3 * syllable)) > 0.95) & bursts
    y = y * envelope + 0.05 * np.max(np.abs(y), initial=0.0) * rng.standard_normal(n) * noisy
    peak = np.max(np.abs(y), initial=0.0)
    return (0.5 * y / peak if peak > 0 else y).astype(np.float32)


def _tts_signal(seconds: float, sr: int) -> np.ndarray:
    from langenv.speech.audio import ClipLibrary

    lib = ClipLibrary(sr=sr, disk_cache=False)
    text = (
        "Hold the handle and follow my lead. We move slowly to the left, then back to the "
        "middle, and once more around the arc. Keep going, you are doing well."
    )
    clip = lib.synthesize(text)
    reps = int(np.ceil(seconds * sr / clip.size))
    return np.tile(clip, reps)[: round(seconds * sr)]


def measure_audio_rtf(
    seconds: float = 20.0,
    *,
    block: int = 512,
    source: Literal["synthetic", "tts"] = "synthetic",
    repeats: int = 3,
) -> float:
    """Seconds of audio rendered per second of wall time, with a varying pace.

    Renders ``seconds`` of content (22.05 kHz mono) through a phase-locked
    ``VariableRateVocoder(22050)`` (n_fft 1024, hop 256): the content is pushed once, then
    pulled in blocks of ``block`` samples with the pace ``a(t) = 1 + 0.4 sin(2 pi t / 3 s)``
    (0.6 to 1.4, a new value every pull). The best of ``repeats`` timed runs is returned (after
    one short warm-up run), so background load inflates the figure least.

    Args:
        seconds: Content duration (s), > 0.
        block: Output samples per pull (the session renderer pulls 512).
        source: ``"synthetic"`` (:func:`speech_like_signal`, fixed seed) or ``"tts"`` (eSpeak NG
            speech repeated to length; needs the eSpeak NG library).
        repeats: Timed runs.

    Returns:
        Output seconds rendered per wall-clock second (``audio_rtf``).
    """
    from langenv.speech.vocoder import VariableRateVocoder

    if not seconds > 0 or block <= 0 or repeats <= 0:
        raise ValueError("seconds, block and repeats must be positive")
    if source == "tts":
        y = _tts_signal(seconds, SR)
    else:
        y = speech_like_signal(seconds, np.random.default_rng(0))

    def render(content: np.ndarray) -> tuple[int, float]:
        voc = VariableRateVocoder(SR)
        t0 = time.perf_counter()
        voc.push(content)
        voc.finish()
        produced = 0
        while not voc.done:
            pace = 1.0 + 0.4 * np.sin(2.0 * np.pi * produced / SR / 3.0)
            produced += voc.pull(block, float(pace)).size
        return produced, time.perf_counter() - t0

    render(y[: SR // 2])  # warm-up: imports, window tables
    best = 0.0
    for _ in range(repeats):
        produced, wall = render(y)
        best = max(best, produced / SR / wall)
    return best
