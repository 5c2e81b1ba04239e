"""Fill numba's disk caches in one process before the test suite's workers start.

Run by ``tests/conftest.py`` (in the xdist controller, as a subprocess) so that two workers never
compile the same cached function at once: librosa's ``pyin``/``stft`` (their numba gufuncs are
cached in librosa's package folder, and numba's gufunc cache is not safe when two processes write
it together, numba issue 10128) and the project's own kernels (:mod:`langenv.batch.warm`).
"""

from __future__ import annotations

import numpy as np


def main() -> None:
    from langenv.batch.warm import warm_up

    seconds = warm_up()
    import librosa

    sr = 16_000
    t = np.arange(sr // 2) / sr
    for dtype in (np.float32, np.float64):
        y = np.sin(2 * np.pi * 150.0 * t).astype(dtype)
        librosa.pyin(y, fmin=70.0, fmax=400.0, sr=sr, frame_length=1024)
        librosa.stft(y, n_fft=2048, hop_length=256)
    print(f"caches warm (langenv kernels {seconds:.1f} s)")


if __name__ == "__main__":
    main()
