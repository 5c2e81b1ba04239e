"""Compile the hot path's kernels once, in one process, before several processes start.

Numba compiles a kernel at its first call and keeps it in a disk cache. When several processes
start together on a machine whose cache is empty (the test suite's workers, ``eval.compare
--workers``, a sweep's workers), each would compile the same kernels at the same moment: minutes
of CPU on a small machine, and two processes writing one cache entry at once is how numba's
cache can be left corrupted (numba issue 10128, for gufuncs). :func:`warm_up` calls every kernel
family the env, the pace laws and the vocoder use, so that the processes started after it load
compiled code (inherited when forked, from the disk cache otherwise) instead of compiling it.

``python -m langenv.batch.warm`` does the same in a process of its own (the test suite's
controller runs it before its workers start).
"""

from __future__ import annotations

import time

import numpy as np

__all__ = ["warm_up"]


def warm_up() -> float:
    """Run a few steps of each compiled path once; returns the seconds it took.

    Covers: the motion-time tables (built at ``make``), the env's compiled ticks at 25 Hz and
    500 Hz, a pace law's compiled steps (:meth:`~langenv.env.LangCtrlEnv.run_law`), the batched
    env's (:mod:`langenv.batch`; its ``prange`` kernel apart: it would start Numba's threads
    before a fork), and the vocoder's pull (:mod:`langenv.speech.vocoder_kernels`). A kernel
    already compiled in this process costs nothing more.
    """
    from langenv.batch import LangCtrlVectorEnv
    from langenv.control.pacing import PaceLaw, PaceLimits
    from langenv.env import LangCtrlEnv
    from langenv.speech.vocoder import time_stretch

    start = time.perf_counter()
    limits = PaceLimits()
    for hz in (25, 500):
        env = LangCtrlEnv(decision_hz=hz)
        env.reset(seed=0)
        for _ in range(3):
            env.step(np.zeros(3, np.float32))  # any action: the kernels are what is warmed
        if hz == 500:
            env.run_law(PaceLaw(k_c=10.0, k_a=limits.k_a, limits=limits), max_steps=5)
        env.close()
    venv = LangCtrlVectorEnv(2, parallel="serial")
    venv.reset(seed=0)
    for _ in range(3):
        venv.step(np.zeros((2, 3), np.float32))
    venv.close()
    sr = 16_000
    tone = np.sin(2 * np.pi * 220.0 * np.arange(sr // 4) / sr).astype(np.float32)
    time_stretch(tone, sr, np.array([0.0, 1.0]), np.array([0.8, 1.2]))
    return time.perf_counter() - start


if __name__ == "__main__":
    print(f"langenv kernels ready in {warm_up():.1f} s")
