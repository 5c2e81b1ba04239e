"""Where the live audio goes: the sound card, or a WAV file fed at the sound card's pace.

Both read the :class:`~langenv.live.ring.AudioRing` one block at a time on their own clock, as a
sound card does, so the loop that fills the ring meets the same deadlines either way; a block the
ring cannot fill is an underrun (silence is played, or written, for the missing part).

:class:`SoundCardSink` uses sounddevice (PortAudio), imported only when it is made: on Linux the
sounddevice wheel needs the system's PortAudio library (Debian/Ubuntu: ``libportaudio2``).
:class:`WavSink` needs nothing: a thread wakes every block period of the monotonic clock and
writes the block to a 16-bit WAV.
"""

from __future__ import annotations

import threading
import time
from pathlib import Path
from typing import Any, Protocol

import numpy as np

from langenv.errors import ConfigError, DeviceError
from langenv.live.ring import AudioRing

__all__ = ["AudioSink", "SoundCardSink", "WavSink", "check_output_device"]

CARD_BLOCK = 256
"""Samples a sink reads per block (11.6 ms at 22.05 kHz)."""


class AudioSink(Protocol):
    """Plays (or records) what the ring holds, in real time."""

    ring: AudioRing

    def start(self) -> None:
        """Start reading the ring on the sink's clock."""

    def stop(self) -> None:
        """Play what is left in the ring, then stop and release the device or file."""

    @property
    def xruns(self) -> int:
        """Underruns the device itself reported (beyond the ring's own count)."""
        ...

    @property
    def alive(self) -> bool:
        """False once the sink, started and not stopped, no longer plays (its thread or stream
        died); True before :meth:`start`."""
        ...


class WavSink:
    """A virtual sound card: reads the ring every block period and writes a 16-bit WAV.

    Args:
        ring: The buffer to read.
        path: The WAV to write (its directory must exist).
        sr: Sample rate (Hz).
        block: Samples per read.
    """

    def __init__(self, ring: AudioRing, path: str | Path, sr: int, block: int = CARD_BLOCK) -> None:
        import soundfile as sf

        self.ring, self.sr, self.block = ring, int(sr), int(block)
        self.path = Path(path)
        if not self.path.parent.is_dir():
            raise ConfigError(f"audio out {self.path}: no directory {self.path.parent}")
        try:
            self._file = sf.SoundFile(self.path, "w", self.sr, 1, "PCM_16")
        except (OSError, RuntimeError) as exc:
            raise ConfigError(f"audio out {self.path}: cannot write: {exc}") from None
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="wav-sink", daemon=True)
        self._started = False
        self.written = 0
        self.error: Exception | None = None
        """What ended the writer thread early (a failed write), or None."""

    @property
    def xruns(self) -> int:
        """A file never underruns by itself."""
        return 0

    @property
    def alive(self) -> bool:
        """False once the writer thread died (a failed write) before :meth:`stop`."""
        return not self._started or self._stop.is_set() or self._thread.is_alive()

    def start(self) -> None:
        """Start the clock."""
        self._started = True
        self._thread.start()

    def _run(self) -> None:
        try:
            self._write_blocks()
        except Exception as exc:  # a failed write ends the thread: alive turns False
            self.error = exc

    def _write_blocks(self) -> None:
        buf = np.zeros(self.block, np.float32)
        period = self.block / self.sr
        t0 = time.monotonic()
        k = 0
        while not self._stop.is_set():
            delay = t0 + k * period - time.monotonic()
            if delay > 0:
                self._stop.wait(delay)
                if self._stop.is_set():
                    break
            self.ring.read_into(buf)
            self._file.write(buf)
            self.written += buf.size
            k += 1

    def stop(self) -> None:
        """Write what is left in the ring (no underrun counted), then close the file."""
        self._stop.set()
        if self._thread.is_alive():
            self._thread.join()
        rest = np.zeros(len(self.ring), np.float32)
        if rest.size:
            self.ring.read_into(rest)
            self._file.write(rest)
            self.written += rest.size
        self._file.close()


def check_output_device(device: Any = None) -> None:
    """Check now, before anything connects or moves, that a :class:`SoundCardSink` can be made
    (sounddevice, PortAudio and an output device ``device``).

    Raises:
        DeviceError: naming what is missing, and ``--audio-out`` as the way round it.
    """
    sd = _sounddevice()
    try:
        sd.query_devices(device, kind="output")
    except (sd.PortAudioError, ValueError) as exc:
        raise DeviceError(
            f"no audio output device ({exc}); write the audio to a file with --audio-out X.wav"
        ) from None


def _sounddevice() -> Any:
    """Import sounddevice, or say what is missing."""
    try:
        import sounddevice
    except ImportError:
        raise DeviceError(
            "live audio needs the sounddevice package (pip install sounddevice); or write the "
            "audio to a file with --audio-out X.wav"
        ) from None
    except OSError as exc:  # the wheel is there but the PortAudio library is not
        raise DeviceError(
            f"live audio needs the PortAudio library ({exc}); on Debian/Ubuntu: apt install "
            "libportaudio2. Or write the audio to a file with --audio-out X.wav"
        ) from None
    return sounddevice


class SoundCardSink:
    """The default output device, through sounddevice (PortAudio), fed from the ring.

    Args:
        ring: The buffer to read.
        sr: Sample rate (Hz).
        block: Samples per callback.
        device: Output device (name or index; default: the system's).

    Raises:
        DeviceError: sounddevice or PortAudio is missing, or there is no output device.
    """

    def __init__(
        self, ring: AudioRing, sr: int, block: int = CARD_BLOCK, device: Any = None
    ) -> None:
        sd = _sounddevice()
        self.ring, self.sr = ring, int(sr)
        self._xruns = 0
        self._started = self._stopping = False
        try:
            sd.query_devices(device, kind="output")
            self._stream = sd.OutputStream(
                samplerate=self.sr,
                blocksize=int(block),
                channels=1,
                dtype="float32",
                latency="low",
                device=device,
                callback=self._callback,
            )
        except (sd.PortAudioError, ValueError) as exc:
            raise DeviceError(
                f"no audio output device ({exc}); write the audio to a file with --audio-out X.wav"
            ) from None

    @property
    def xruns(self) -> int:
        """Output underflows PortAudio reported."""
        return self._xruns

    def _callback(self, outdata: np.ndarray, frames: int, time_info: Any, status: Any) -> None:
        if status.output_underflow:
            self._xruns += 1
        self.ring.read_into(outdata[:, 0])

    @property
    def alive(self) -> bool:
        """False once the stream stopped by itself (a callback error, the device gone) before
        :meth:`stop`."""
        return not self._started or self._stopping or bool(self._stream.active)

    def start(self) -> None:
        """Start playing."""
        self._started = True
        self._stream.start()

    def stop(self) -> None:
        """Let the ring drain, then stop and close the stream."""
        self._stopping = True
        underruns, missing = self.ring.underruns, self.ring.missing
        deadline = time.monotonic() + len(self.ring) / self.sr + 0.2
        while len(self.ring) and time.monotonic() < deadline:
            time.sleep(0.01)
        self._stream.stop()
        self._stream.close()
        self.ring.underruns, self.ring.missing = underruns, missing  # draining is no underrun
