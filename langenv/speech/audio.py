"""Phrase audio: recorded clips from files, or offline text-to-speech with eSpeak NG, cached.

A phrase of a :class:`~langenv.speech.graph.PhraseGraph` sounds like its ``audio`` file when it
has one (a lab's recorded voice: any sample rate libsndfile reads, mono or stereo) and otherwise
like its ``text`` spoken by eSpeak NG. eSpeak NG (GPL-3.0-or-later) ships as a shared library in
the ``espeakng-loader`` wheel (MIT); it is driven here through :mod:`ctypes` in synchronous
retrieval mode, so nothing is played and no other program is needed. Synthesised clips are cached
on disk (``$LANGCTRL_CACHE`` or ``~/.cache/langctrl/tts``) keyed by a hash of the text, the voice
settings and the engine version, and in memory.

All clips are mono ``float32`` arrays at the library's sample rate, with leading and trailing
silence trimmed, so a phrase's duration is the length of its sound. eSpeak NG's output varies by
a few samples from call to call; the cache is what keeps a phrase's clip (and duration) fixed.
"""

from __future__ import annotations

import ctypes
import hashlib
import json
import os
import tempfile
import threading
import warnings
from pathlib import Path
from typing import Any, Protocol

import numpy as np

from langenv.errors import AudioError, ConfigError

__all__ = [
    "DEFAULT_RATE",
    "DEFAULT_SR",
    "DEFAULT_VOICE",
    "ClipLibrary",
    "SpokenPhrase",
    "default_cache_dir",
]


class SpokenPhrase(Protocol):
    """What a clip is made from (a :class:`~langenv.speech.graph.Phrase` is one)."""

    @property
    def id(self) -> str:
        """Phrase id, named in error messages."""
        ...

    @property
    def text(self) -> str | None:
        """The words, spoken by eSpeak NG when there is no ``audio``."""
        ...

    @property
    def audio(self) -> Path | None:
        """A recorded clip."""
        ...


DEFAULT_SR = 22050
"""Sample rate of the clips (Hz): eSpeak NG's native rate."""
DEFAULT_VOICE = "en-us"
"""eSpeak NG voice (falls back to ``"en"`` when absent)."""
DEFAULT_RATE = 150
"""Speaking rate (words per minute): an unhurried conversational rate, as a therapist speaks."""
DEFAULT_PITCH = 50
"""eSpeak NG base pitch (0-100; 50 is the voice's default)."""

_CACHE_FORMAT = 1  # bump when the stored clip's meaning changes (trim, normalisation, ...)

# eSpeak NG API constants (speak_lib.h)
_AUDIO_OUTPUT_SYNCHRONOUS = 2
_POS_CHARACTER = 1
_ESPEAK_CHARS_UTF8 = 1
_ESPEAK_RATE = 1
_ESPEAK_VOLUME = 2
_ESPEAK_PITCH = 3
_EE_OK = 0
_SYNTH_CALLBACK = ctypes.CFUNCTYPE(
    ctypes.c_int, ctypes.POINTER(ctypes.c_short), ctypes.c_int, ctypes.c_void_p
)


def default_cache_dir() -> Path:
    """Directory of the on-disk TTS cache: ``$LANGCTRL_CACHE`` or ``~/.cache/langctrl/tts``."""
    env = os.environ.get("LANGCTRL_CACHE")
    if env:
        return Path(env).expanduser()
    return Path.home() / ".cache" / "langctrl" / "tts"


class _ESpeak:
    """The process-wide eSpeak NG library (it keeps global state), used under a lock."""

    _instance: _ESpeak | None = None
    _create_lock = threading.Lock()

    def __init__(self) -> None:
        try:
            import espeakng_loader
        except ImportError as exc:  # pragma: no cover - a declared dependency
            raise AudioError(
                "text-to-speech needs eSpeak NG from the 'espeakng-loader' package "
                "(pip install espeakng-loader), or give every phrase an 'audio' file"
            ) from exc
        lib_path = espeakng_loader.get_library_path()
        try:
            data_path = espeakng_loader.get_data_path()
            lib = ctypes.CDLL(lib_path)
        except (OSError, RuntimeError) as exc:
            raise AudioError(f"cannot load eSpeak NG from {lib_path}: {exc}") from exc
        lib.espeak_Initialize.argtypes = [ctypes.c_int, ctypes.c_int, ctypes.c_char_p, ctypes.c_int]
        lib.espeak_Initialize.restype = ctypes.c_int
        lib.espeak_SetSynthCallback.argtypes = [_SYNTH_CALLBACK]
        lib.espeak_SetSynthCallback.restype = None
        lib.espeak_SetParameter.argtypes = [ctypes.c_int, ctypes.c_int, ctypes.c_int]
        lib.espeak_SetParameter.restype = ctypes.c_int
        lib.espeak_SetVoiceByName.argtypes = [ctypes.c_char_p]
        lib.espeak_SetVoiceByName.restype = ctypes.c_int
        lib.espeak_Synth.argtypes = [
            ctypes.c_void_p,
            ctypes.c_size_t,
            ctypes.c_uint,
            ctypes.c_int,
            ctypes.c_uint,
            ctypes.c_uint,
            ctypes.c_void_p,
            ctypes.c_void_p,
        ]
        lib.espeak_Synth.restype = ctypes.c_int
        lib.espeak_Info.argtypes = [ctypes.c_void_p]
        lib.espeak_Info.restype = ctypes.c_char_p
        sr = lib.espeak_Initialize(_AUDIO_OUTPUT_SYNCHRONOUS, 0, data_path.encode(), 0)
        if sr <= 0:
            raise AudioError(f"eSpeak NG failed to initialise with data at {data_path}")
        self.lib = lib
        self.sr = int(sr)
        self.version = (lib.espeak_Info(None) or b"unknown").decode()
        self._chunks: list[np.ndarray] = []
        self._callback = _SYNTH_CALLBACK(self._collect)  # keep a reference: C holds a pointer
        lib.espeak_SetSynthCallback(self._callback)
        self.lock = threading.Lock()

    @classmethod
    def get(cls) -> _ESpeak:
        with cls._create_lock:
            if cls._instance is None:
                cls._instance = cls()
            return cls._instance

    def _collect(self, wav: Any, n: int, _events: Any) -> int:
        if n > 0 and wav:
            self._chunks.append(np.ctypeslib.as_array(wav, shape=(n,)).copy())
        return 0  # 0: go on synthesising

    def synthesize(self, text: str, voice: str, rate: int, pitch: int) -> np.ndarray:
        """``text`` spoken at ``rate`` wpm: int16 samples at :attr:`sr`."""
        with self.lock:
            lib = self.lib
            for name in (voice, "en") if voice == DEFAULT_VOICE else (voice,):
                if lib.espeak_SetVoiceByName(name.encode()) == _EE_OK:
                    break
            else:
                raise AudioError(f"eSpeak NG has no voice {voice!r}")
            lib.espeak_SetParameter(_ESPEAK_RATE, int(rate), 0)
            lib.espeak_SetParameter(_ESPEAK_PITCH, int(pitch), 0)
            lib.espeak_SetParameter(_ESPEAK_VOLUME, 100, 0)
            data = text.encode("utf-8")
            buf = ctypes.create_string_buffer(data)
            self._chunks = []
            err = lib.espeak_Synth(
                buf, len(data) + 1, 0, _POS_CHARACTER, 0, _ESPEAK_CHARS_UTF8, None, None
            )
            chunks, self._chunks = self._chunks, []
        if err != _EE_OK:
            raise AudioError(f"eSpeak NG failed (error {err}) to synthesise {text!r}")
        if not chunks:
            return np.zeros(0, np.int16)
        return np.concatenate(chunks)


def trim_silence(y: np.ndarray, sr: int, top_db: float = 40.0) -> np.ndarray:
    """Cut leading and trailing silence.

    Args:
        y: Mono signal, shape ``(n,)``.
        sr: Its sample rate (Hz).
        top_db: Frames (23 ms at 22.05 kHz, hop a quarter of that) whose RMS lies more than
            ``top_db`` dB below the loudest frame's count as silence.

    Returns:
        The slice of ``y`` from the first to the last sample louder than that floor within the
        first and last non-silent frames (a view).
    """
    frame = max(16, round(0.023 * sr))
    hop = max(1, frame // 4)
    if y.size <= frame:
        return y
    windows = np.lib.stride_tricks.sliding_window_view(y, frame)[::hop]
    rms = np.sqrt(np.mean(np.square(windows, dtype=np.float64), axis=1))
    peak = float(rms.max())
    if peak <= 0.0:
        return y[:0]
    floor = peak * 10.0 ** (-top_db / 20.0)
    loud = np.flatnonzero(rms > floor)
    lo = int(loud[0]) * hop
    hi = min(y.size, int(loud[-1]) * hop + frame)
    # refine to the sample inside the edge frames: first/last sample above the RMS floor
    head = np.flatnonzero(np.abs(y[lo : lo + frame]) > floor)
    tail = np.flatnonzero(np.abs(y[max(lo, hi - frame) : hi]) > floor)
    if head.size:
        lo += int(head[0])
    if tail.size:
        hi = max(lo, hi - frame) + int(tail[-1]) + 1
    return y[lo:hi]


class ClipLibrary:
    """Audio of phrases, from recorded files or eSpeak NG, cached on disk and in memory.

    Args:
        sr: Sample rate of every clip it returns (Hz); files and TTS are resampled to it (soxr).
        cache_dir: Directory of the on-disk TTS cache; ``None``: :func:`default_cache_dir`.
        voice: eSpeak NG voice name (``"en-us"`` falls back to ``"en"``).
        rate: Speaking rate, words per minute (80-450).
        pitch: eSpeak NG base pitch, 0-100.
        trim_db: Leading/trailing silence threshold (dB below the loudest frame) for synthesised
            and recorded clips; ``None`` keeps recorded files as they are (TTS is always trimmed
            at 40 dB).
        disk_cache: Keep synthesised clips on disk; when the cache directory cannot be written,
            a warning is issued once and clips stay in memory only.

    Raises:
        ConfigError: naming the argument, when one is out of range.
    """

    def __init__(
        self,
        sr: int = DEFAULT_SR,
        cache_dir: str | Path | None = None,
        *,
        voice: str = DEFAULT_VOICE,
        rate: int = DEFAULT_RATE,
        pitch: int = DEFAULT_PITCH,
        trim_db: float | None = 40.0,
        disk_cache: bool = True,
    ) -> None:
        if isinstance(sr, bool) or not isinstance(sr, int) or not 4000 <= sr <= 192000:
            raise ConfigError(f"ClipLibrary: sr must be an int in [4000, 192000] Hz, got {sr!r}")
        if not isinstance(voice, str) or not voice.strip():
            raise ConfigError(f"ClipLibrary: voice must be a non-empty str, got {voice!r}")
        if isinstance(rate, bool) or not isinstance(rate, int) or not 80 <= rate <= 450:
            raise ConfigError(f"ClipLibrary: rate must be an int in [80, 450] wpm, got {rate!r}")
        if isinstance(pitch, bool) or not isinstance(pitch, int) or not 0 <= pitch <= 100:
            raise ConfigError(f"ClipLibrary: pitch must be an int in [0, 100], got {pitch!r}")
        if trim_db is not None and not (isinstance(trim_db, int | float) and 0.0 < trim_db < 120.0):
            raise ConfigError(
                f"ClipLibrary: trim_db must be in (0, 120) dB or None, got {trim_db!r}"
            )
        self.sr = sr
        self.voice = voice
        self.rate = rate
        self.pitch = pitch
        self.trim_db = None if trim_db is None else float(trim_db)
        self.cache_dir: Path | None = (
            (Path(cache_dir).expanduser() if cache_dir is not None else default_cache_dir())
            if disk_cache
            else None
        )
        self._memory: dict[tuple[Any, ...], np.ndarray] = {}
        self._warned_cache = False

    def __repr__(self) -> str:
        return (
            f"ClipLibrary(sr={self.sr}, voice={self.voice!r}, rate={self.rate}, "
            f"pitch={self.pitch}, cache_dir={self.cache_dir})"
        )

    # ------------------------------------------------------------------ public API
    def clip(self, phrase: SpokenPhrase) -> np.ndarray:
        """The audio of ``phrase``: its ``audio`` file if it has one, else its ``text`` spoken.

        Returns:
            Read-only mono ``float32`` array, shape ``(n,)``, at :attr:`sr`.

        Raises:
            AudioError: naming the file and the phrase, when the file is missing or unreadable
                or the clip is silent.
        """
        if phrase.audio is not None:
            return self.load_file(phrase.audio, phrase=phrase.id)
        if phrase.text is None:
            raise AudioError(f"phrase {phrase.id!r} has neither text nor audio")
        return self.synthesize(phrase.text, phrase=phrase.id)

    def duration(self, phrase: SpokenPhrase) -> float:
        """Length of the phrase's clip at pace 1 (s)."""
        return self.clip(phrase).size / self.sr

    def load_file(self, path: str | Path, *, phrase: str | None = None) -> np.ndarray:
        """A recorded clip: any format libsndfile reads, mixed to mono, resampled to :attr:`sr`.

        Args:
            path: The audio file.
            phrase: Phrase id, named in error messages.

        Returns:
            Read-only mono ``float32`` array, shape ``(n,)``, trimmed when ``trim_db`` is set.

        Raises:
            AudioError: naming the file (and phrase), when it is missing, unreadable or silent.
        """
        path = Path(path)
        where = f"{path}" + (f" (phrase {phrase!r})" if phrase else "")
        try:
            st = path.stat()
        except OSError as exc:
            raise AudioError(f"{where}: cannot read audio file: {exc.strerror or exc}") from None
        key = ("file", str(path.resolve()), st.st_mtime_ns, st.st_size)
        cached = self._memory.get(key)
        if cached is not None:
            return cached
        import soundfile as sf

        try:
            data, file_sr = sf.read(str(path), dtype="float32", always_2d=True)
        except (RuntimeError, OSError, ValueError, TypeError) as exc:
            raise AudioError(f"{where}: unreadable audio file: {exc}") from None
        y = np.ascontiguousarray(data.mean(axis=1), dtype=np.float32)
        if not np.all(np.isfinite(y)):
            raise AudioError(f"{where}: audio file contains NaN or infinite samples")
        y = self._resample(y, int(file_sr))
        if self.trim_db is not None:
            y = np.ascontiguousarray(trim_silence(y, self.sr, self.trim_db))
        if y.size == 0 or not np.any(y):
            raise AudioError(f"{where}: audio file is empty or silent")
        return self._remember(key, y)

    def synthesize(self, text: str, *, phrase: str | None = None) -> np.ndarray:
        """``text`` spoken by eSpeak NG with this library's voice, rate and pitch.

        Args:
            text: What to say (plain text, UTF-8).
            phrase: Phrase id, named in error messages.

        Returns:
            Read-only mono ``float32`` array, shape ``(n,)``, at :attr:`sr`, silence trimmed.

        Raises:
            AudioError: when eSpeak NG cannot be loaded or produces no sound.
        """
        if not isinstance(text, str) or not text.strip():
            raise AudioError(f"phrase {phrase!r}: nothing to synthesise (empty text)")
        engine = _ESpeak.get()
        key = ("tts", self._tts_key(text, engine.version))
        cached = self._memory.get(key)
        if cached is not None:
            return cached
        y = self._read_cache(key[1])
        if y is None:
            raw = engine.synthesize(text, self.voice, self.rate, self.pitch)
            y = raw.astype(np.float32) / np.float32(32768.0)
            y = np.ascontiguousarray(trim_silence(y, engine.sr, self.trim_db or 40.0))
            y = self._resample(y, engine.sr)
            if y.size == 0 or not np.any(y):
                who = f"phrase {phrase!r}: " if phrase else ""
                raise AudioError(f"{who}eSpeak NG produced no sound for {text!r}")
            self._write_cache(key[1], y)
        return self._remember(key, y)

    # ------------------------------------------------------------------ internals
    def _tts_key(self, text: str, version: str) -> str:
        ident = {
            "engine": "espeak-ng",
            "version": version,
            "voice": self.voice,
            "rate": self.rate,
            "pitch": self.pitch,
            "sr": self.sr,
            "trim_db": self.trim_db or 40.0,
            "format": _CACHE_FORMAT,
            "text": text,
        }
        return hashlib.sha256(json.dumps(ident, sort_keys=True).encode()).hexdigest()

    def _resample(self, y: np.ndarray, sr_in: int) -> np.ndarray:
        if sr_in == self.sr:
            return y
        import soxr

        return np.ascontiguousarray(soxr.resample(y, sr_in, self.sr), dtype=np.float32)

    def _remember(self, key: tuple[Any, ...], y: np.ndarray) -> np.ndarray:
        y = np.array(y, dtype=np.float32, copy=True)
        y.setflags(write=False)
        self._memory[key] = y
        return y

    def _read_cache(self, digest: str) -> np.ndarray | None:
        if self.cache_dir is None:
            return None
        path = self.cache_dir / f"{digest}.npy"
        try:
            y = np.load(path, allow_pickle=False)
        except (OSError, ValueError):
            return None
        if y.ndim != 1 or y.dtype != np.float32 or y.size == 0:
            return None
        return y

    def _write_cache(self, digest: str, y: np.ndarray) -> None:
        if self.cache_dir is None:
            return
        try:
            self.cache_dir.mkdir(parents=True, exist_ok=True)
            fd, tmp = tempfile.mkstemp(dir=self.cache_dir, suffix=".npy.part")
            try:
                with os.fdopen(fd, "wb") as f:
                    np.save(f, y, allow_pickle=False)
                os.replace(tmp, self.cache_dir / f"{digest}.npy")
            except BaseException:
                Path(tmp).unlink(missing_ok=True)
                raise
        except OSError as exc:
            if not self._warned_cache:
                warnings.warn(
                    f"TTS cache directory {self.cache_dir} is not writable ({exc}); "
                    "clips are kept in memory only",
                    RuntimeWarning,
                    stacklevel=3,
                )
                self._warned_cache = True
