"""The audio buffer between the real-time loop (the writer) and a sound card (the reader)."""

from __future__ import annotations

import threading

import numpy as np

from langenv.errors import ConfigError

__all__ = ["AudioRing"]


class AudioRing:
    """A fixed-size, thread-safe FIFO of mono float32 samples.

    The loop writes what the vocoder renders; the sound card's callback reads a block at a time.
    A read that finds fewer samples than it asks for is an *underrun*: the card plays silence for
    the missing part, and the count goes up. A write that does not fit is refused in part (the
    loop then renders less until the card catches up), so nothing is ever overwritten.

    Args:
        capacity: Most samples held (> 0).

    Attributes:
        underruns: Reads that came up short since the ring was made.
        missing: Samples those reads lacked (played as silence).
    """

    def __init__(self, capacity: int) -> None:
        if isinstance(capacity, bool) or not isinstance(capacity, int) or capacity <= 0:
            raise ConfigError(f"capacity must be a positive integer (samples), got {capacity!r}")
        self._buf = np.zeros(capacity, np.float32)
        self._start = 0  # index of the oldest sample
        self._size = 0
        self._lock = threading.Lock()
        self.underruns = 0
        self.missing = 0

    @property
    def capacity(self) -> int:
        """Most samples held."""
        return int(self._buf.size)

    def __len__(self) -> int:
        with self._lock:
            return self._size

    def free(self) -> int:
        """Samples that can be written now."""
        with self._lock:
            return self._buf.size - self._size

    def write(self, x: np.ndarray) -> int:
        """Append as many samples of ``x`` (shape (n,)) as fit; returns how many were taken."""
        x = np.asarray(x, np.float32).reshape(-1)
        with self._lock:
            cap = self._buf.size
            n = min(x.size, cap - self._size)
            end = (self._start + self._size) % cap
            first = min(n, cap - end)
            self._buf[end : end + first] = x[:first]
            self._buf[: n - first] = x[first:n]
            self._size += n
            return n

    def read_into(self, out: np.ndarray) -> int:
        """Fill ``out`` (shape (n,), float32) with the oldest samples, silence where there are
        none (an underrun); returns the number of real samples."""
        with self._lock:
            cap = self._buf.size
            n = min(out.size, self._size)
            first = min(n, cap - self._start)
            out[:first] = self._buf[self._start : self._start + first]
            out[first:n] = self._buf[: n - first]
            out[n:] = 0.0
            self._start = (self._start + n) % cap
            self._size -= n
            if n < out.size:
                self.underruns += 1
                self.missing += out.size - n
            return n

    def fade_out(self, samples: int) -> None:
        """Keep at most ``samples`` of what is queued, ramped linearly down to silence; drop the
        rest (the speech fades out instead of being cut)."""
        with self._lock:
            n = max(0, min(int(samples), self._size))
            cap = self._buf.size
            idx = (self._start + np.arange(n)) % cap
            self._buf[idx] *= np.linspace(1.0, 0.0, n, dtype=np.float32)
            self._size = n
