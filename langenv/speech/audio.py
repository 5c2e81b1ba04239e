"""Phrase audio: recorded clips from files, or offline text-to-speech with eSpeak NG, cached.

A phrase of a :class:`~langenv.speech.graph.PhraseGraph` sounds like its ``audio`` file when it
has one (a lab's recorded voice: any sample rate libsndfile reads, mono or stereo) and otherwise
like its ``text`` spoken by eSpeak NG. eSpeak NG (GPL-3.0-or-later) ships as a shared library in
the ``espeakng-loader`` wheel (MIT); it is driven through :mod:`ctypes` in synchronous retrieval
mode by a worker process (:mod:`langenv.speech.espeak_worker`) that says every text from the
library's freshly initialised state, so nothing is played, no other program is needed, and a clip
is a pure function of its text, the voice settings and the engine's version (eSpeak NG carries
state from one utterance to the next; the worker's docstring says which). Synthesised clips are
cached on disk (``$LANGCTRL_CACHE`` or ``~/.cache/langctrl/tts``) keyed by a hash of the text, the
voice settings and the engine version, and in memory; the cache saves time, it does not decide
the samples. ``langenv/assets/tts_manifest.json`` pins the length and digest of every shipped
phrase (a test compares them).

All clips are mono ``float32`` arrays at the library's sample rate, with leading and trailing
silence trimmed, so a phrase's duration is the length of its sound.
"""

from __future__ import annotations

import atexit
import hashlib
import json
import os
import subprocess
import sys
import threading
import warnings
from collections.abc import Callable
from pathlib import Path
from typing import Any, Protocol

import numpy as np

from langenv.errors import AudioError, ConfigError
from langenv.files import temp_file

__all__ = [
    "DEFAULT_RATE",
    "DEFAULT_SR",
    "DEFAULT_VOICE",
    "ClipLibrary",
    "ESpeakEngine",
    "SpokenPhrase",
    "default_cache_dir",
]


class SpokenPhrase(Protocol):
    """What a clip is made from (a :class:`~langenv.speech.phrase.Phrase` is one)."""

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

_CACHE_FORMAT = 2  # bump when the stored clip's meaning changes (trim, normalisation, ...)
# 2: every clip said from the engine's clean state (espeak_worker), no longer order-dependent


def default_cache_dir() -> Path:
    """Directory of the on-disk TTS cache: ``$LANGCTRL_CACHE`` or ``~/.cache/langctrl/tts``."""
    env = os.environ.get("LANGCTRL_CACHE")
    if env:
        return Path(env).expanduser()
    return Path.home() / ".cache" / "langctrl" / "tts"


#: The workers this process started and has not ended, by the pid that started them: the one
#: exit handler ends them (one handler, however many workers come and go: on Windows, without
#: fork, a worker serves one request; elsewhere a worker ends after a failed exchange).
_WORKERS: dict[subprocess.Popen[bytes], int] = {}


def _stop_workers() -> None:
    """At exit, end the workers this process started (not a forked parent's)."""
    pid = os.getpid()
    for proc, owner in list(_WORKERS.items()):
        if owner == pid:
            ESpeakEngine._stop(proc)


atexit.register(_stop_workers)


class ESpeakEngine:
    """eSpeak NG behind a worker process that says every text from the same clean state.

    The worker (:mod:`langenv.speech.espeak_worker`) is started on first use and serves this
    process (one per process: a process forked from this one starts its own); each text is said
    by a child forked from the worker's freshly initialised library, so a clip is a pure
    function of its text, the voice settings and :attr:`version`, whatever was synthesised
    before. Thread-safe (one request at a time).

    Raises:
        AudioError: when the library cannot be loaded or the worker fails.
    """

    _instance: ESpeakEngine | None = None
    _create_lock = threading.Lock()

    def __init__(self) -> None:
        self.lock = threading.Lock()
        self._proc: subprocess.Popen[bytes] | None = None  # a worker in step with this client
        self._pid = -1
        self.sr, self.version, self._one_shot = self._start()

    @classmethod
    def get(cls) -> ESpeakEngine:
        """The process's engine (started on first use)."""
        with cls._create_lock:
            if cls._instance is None or cls._instance._pid != os.getpid():
                cls._instance = cls()
            return cls._instance

    def _start(self) -> tuple[int, str, bool]:
        try:
            import espeakng_loader  # noqa: F401  (the worker needs it: say so here, by name)
        except ImportError as exc:  # pragma: no cover - a declared dependency
            raise AudioError(
                "text-to-speech needs eSpeak NG from the 'espeakng-loader' package "
                "(pip install espeakng-loader), or give every phrase an 'audio' file"
            ) from exc
        from langenv.speech import espeak_worker

        self._proc = None
        proc = subprocess.Popen(
            [sys.executable, espeak_worker.__file__],
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
        )
        _WORKERS[proc] = os.getpid()
        try:  # the worker is used only once its greeting is read (an interrupt ends it)
            hello = self._read_header(proc)
            if "error" in hello:
                raise AudioError(str(hello["error"]))
            info = int(hello["sr"]), str(hello["version"]), bool(hello["one_shot"])
        except BaseException:
            self._end(proc)
            raise
        self._proc, self._pid = proc, os.getpid()
        return info

    @staticmethod
    def _stop(proc: subprocess.Popen[bytes]) -> None:
        """End a worker: close its input (it exits at end of input) and reap it."""
        _WORKERS.pop(proc, None)
        if proc.poll() is None and proc.stdin is not None:
            try:
                proc.stdin.close()
                proc.wait(timeout=5)
            except (OSError, subprocess.TimeoutExpired):
                proc.kill()

    @staticmethod
    def _end(proc: subprocess.Popen[bytes]) -> None:
        """End a worker whose pipes may be out of step (an exchange that did not finish): kill
        it and reap it, so that nothing it wrote is ever read as another text's answer."""
        _WORKERS.pop(proc, None)
        try:
            proc.kill()
            proc.wait(timeout=5)
        except (OSError, subprocess.TimeoutExpired):  # pragma: no cover - already gone
            pass
        for pipe in (proc.stdin, proc.stdout):
            try:
                if pipe is not None:
                    pipe.close()
            except OSError:  # pragma: no cover - a broken pipe's unflushed request
                pass

    @staticmethod
    def _read_header(proc: subprocess.Popen[bytes]) -> dict[str, Any]:
        """The worker's next header line (``{"error": ...}`` included).

        Raises:
            AudioError: when the worker has ended or its line is not a header.
        """
        assert proc.stdout is not None
        raw = proc.stdout.readline()
        if not raw:
            code = proc.wait()
            raise AudioError(f"the eSpeak NG worker ended unexpectedly (exit status {code})")
        try:
            header = json.loads(raw)
        except ValueError:
            header = None
        if not isinstance(header, dict):
            raise AudioError(f"the eSpeak NG worker wrote {raw[:80]!r}, not a header line")
        return header

    def synthesize(self, text: str, voice: str, rate: int, pitch: int) -> np.ndarray:
        """``text`` spoken at ``rate`` wpm: int16 samples at :attr:`sr`.

        An exchange that does not finish (an error, a worker that ends, an interrupt such as
        Ctrl-C) ends the worker, so the next request, to a new one, cannot read its answer.

        Raises:
            AudioError: naming the text, when the worker reports an error or ends.
        """
        request = json.dumps({"text": text, "voice": voice, "rate": rate, "pitch": pitch})
        with self.lock:
            if self._proc is None or self._pid != os.getpid() or self._proc.poll() is not None:
                self._start()
            proc = self._proc
            assert proc is not None and proc.stdin is not None and proc.stdout is not None
            self._proc = None  # back only once the exchange is complete
            try:
                proc.stdin.write(request.encode() + b"\n")
                proc.stdin.flush()
                header = self._read_header(proc)
                size = 2 * int(header.get("n", 0))
                data = proc.stdout.read(size)
                if len(data) != size:
                    raise AudioError(
                        f"the eSpeak NG worker's answer was cut short ({len(data)} of {size} bytes)"
                    )
            except BaseException as exc:
                self._end(proc)
                if isinstance(exc, AudioError | OSError | ValueError | TypeError):
                    raise AudioError(f"eSpeak NG failed to synthesise {text!r}: {exc}") from exc
                raise
            if self._one_shot:
                proc.wait()
                _WORKERS.pop(proc, None)
                for pipe in (proc.stdin, proc.stdout):
                    pipe.close()
            else:
                self._proc = proc
        if "error" in header:
            raise AudioError(str(header["error"]))
        return np.frombuffer(data, dtype=np.int16).copy()

    @classmethod
    def _after_fork_in_child(cls) -> None:
        """A forked process gets a class lock of its own: one that a thread of the parent held
        at the fork (inside :meth:`get`) would never be released in the child."""
        cls._create_lock = threading.Lock()


if hasattr(os, "register_at_fork"):
    os.register_at_fork(after_in_child=ESpeakEngine._after_fork_in_child)


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
        self._lengths: dict[tuple[Any, ...], int] = {}
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
        """Length of the phrase's clip at pace 1 (s): :meth:`samples` over :attr:`sr`."""
        return self.samples(phrase) / self.sr

    def samples(self, phrase: SpokenPhrase) -> int:
        """Length of the phrase's clip (samples at :attr:`sr`), measured without keeping its
        audio: a graph needs its clips' lengths, and only what renders them needs their sound
        (:meth:`clip` loads it there). A synthesised clip is measured from the disk cache
        without reading its samples; one that the disk cannot keep (no disk cache, or one that
        cannot be written) stays in memory, so that it is not synthesised twice.

        Raises:
            AudioError: as :meth:`clip`.
        """
        audio, text = phrase.audio, phrase.text
        if audio is not None:
            key, where = self._file_key(audio, phrase.id)
            return self._samples(key, lambda: int(self._read_file(Path(audio), where).size))
        if text is None:
            raise AudioError(f"phrase {phrase.id!r} has neither text nor audio")
        engine, tts = self._tts_ident(text, phrase.id)
        return self._samples(tts, lambda: self._tts_samples(text, phrase.id, engine, tts))

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
        key, where = self._file_key(path, phrase)
        cached = self._memory.get(key)
        if cached is not None:
            return cached
        return self._remember(key, self._read_file(Path(path), where))

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
        engine, key = self._tts_ident(text, phrase)
        cached = self._memory.get(key)
        if cached is not None:
            return cached
        y = self._read_cache(key[1])
        if y is None:
            y = self._spoken(text, phrase, engine)
            self._write_cache(key[1], y)
        return self._remember(key, y)

    # ------------------------------------------------------------------ internals
    def _samples(self, key: tuple[Any, ...], measure: Callable[[], int]) -> int:
        """The length of clip ``key``: from memory, from the lengths measured, or ``measure()``
        (remembered)."""
        clip = self._memory.get(key)
        if clip is not None:
            return int(clip.size)
        n = self._lengths.get(key)
        if n is None:
            n = self._lengths[key] = measure()
        return n

    def _file_key(self, path: str | Path, phrase: str | None) -> tuple[tuple[Any, ...], str]:
        """A recorded clip's key (its file's path, time and size) and its name in errors."""
        path = Path(path)
        where = f"{path}" + (f" (phrase {phrase!r})" if phrase else "")
        try:
            st = path.stat()
        except OSError as exc:
            raise AudioError(f"{where}: cannot read audio file: {exc.strerror or exc}") from None
        return ("file", str(path.resolve()), st.st_mtime_ns, st.st_size), where

    def _read_file(self, path: Path, where: str) -> np.ndarray:
        """A recorded clip read, mixed to mono, resampled and trimmed (not remembered)."""
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
        return y

    def _tts_ident(self, text: str, phrase: str | None) -> tuple[ESpeakEngine, tuple[str, str]]:
        """The engine and the key of ``text`` said with this library's settings."""
        if not isinstance(text, str) or not text.strip():
            raise AudioError(f"phrase {phrase!r}: nothing to synthesise (empty text)")
        engine = ESpeakEngine.get()
        return engine, ("tts", self._tts_key(text, engine.version))

    def _spoken(self, text: str, phrase: str | None, engine: ESpeakEngine) -> np.ndarray:
        """``text`` synthesised, trimmed and resampled (not cached)."""
        raw = engine.synthesize(text, self.voice, self.rate, self.pitch)
        y = raw.astype(np.float32) / np.float32(32768.0)
        y = np.ascontiguousarray(trim_silence(y, engine.sr, self.trim_db or 40.0))
        y = self._resample(y, engine.sr)
        if y.size == 0 or not np.any(y):
            who = f"phrase {phrase!r}: " if phrase else ""
            raise AudioError(f"{who}eSpeak NG produced no sound for {text!r}")
        return y

    def _tts_samples(
        self, text: str, phrase: str | None, engine: ESpeakEngine, key: tuple[str, str]
    ) -> int:
        """The length of ``text``'s clip: from its header in the disk cache, or synthesised
        (and kept in memory when the disk cannot keep it)."""
        cached = self._read_cache(key[1], mmap=True)
        if cached is not None:
            return int(cached.size)
        y = self._spoken(text, phrase, engine)
        if not self._write_cache(key[1], y):
            self._remember(key, y)
        return int(y.size)

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

    def _read_cache(self, digest: str, *, mmap: bool = False) -> np.ndarray | None:
        """A clip from the disk cache, or None; ``mmap``: mapped, its samples not read."""
        if self.cache_dir is None:
            return None
        path = self.cache_dir / f"{digest}.npy"
        try:
            y = np.load(path, mmap_mode="r" if mmap else None, allow_pickle=False)
        except (OSError, ValueError):
            return None
        if y.ndim != 1 or y.dtype != np.float32 or y.size == 0:
            return None
        return y

    def _write_cache(self, digest: str, y: np.ndarray) -> bool:
        """``y`` into the disk cache; whether it is there."""
        if self.cache_dir is None:
            return False
        try:
            self.cache_dir.mkdir(parents=True, exist_ok=True)
            fd, tmp = temp_file(self.cache_dir, suffix=".npy.part")
            try:
                with os.fdopen(fd, "wb") as f:
                    np.save(f, y, allow_pickle=False)
                os.replace(tmp, self.cache_dir / f"{digest}.npy")
            except BaseException:
                tmp.unlink(missing_ok=True)
                raise
            return True
        except OSError as exc:
            if not self._warned_cache:
                warnings.warn(
                    f"TTS cache directory {self.cache_dir} is not writable ({exc}); "
                    "clips are kept in memory only",
                    RuntimeWarning,
                    stacklevel=3,
                )
                self._warned_cache = True
            return False
