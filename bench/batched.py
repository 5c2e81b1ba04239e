"""The batched env (``langenv.batch``) against the single env, measured alternating in one run.

One round steps the single ``LangCtrl-v0`` (25 Hz, a fixed action) for ``single_steps`` steps,
its episodes' resets included, then the batched env of ``sessions`` sessions (the same settings,
``SAME_STEP`` autoreset, all cores) for as many session-steps; the rounds alternate, so both
see the same load from other programs. Each figure is the median over the rounds, and the ratio
is the median of the rounds' ratios.
"""

from __future__ import annotations

import os
import time
from typing import Any

import numpy as np

__all__ = ["measure_batched"]


def measure_batched(
    sessions: int = 32, rounds: int = 7, single_steps: int = 1500, parallel: str = "pool"
) -> dict[str, float]:
    """Steps per second of the single env and of the batched env, alternating.

    Returns:
        ``single_steps_per_s``, ``batched_steps_per_s`` (session-steps per second, all sessions
        together), ``batched_ratio`` (the median of the rounds' ratios), ``batched_sessions``,
        ``batched_threads`` and ``load_1min`` (the 1-minute load average at the end).
    """
    from gymnasium.vector import AutoresetMode

    from langenv.batch import LangCtrlVectorEnv
    from langenv.env import LangCtrlEnv

    single = LangCtrlEnv(decision_hz=25)
    batch = LangCtrlVectorEnv(
        sessions,
        decision_hz=25,
        max_episode_steps=1500,
        autoreset_mode=AutoresetMode.SAME_STEP,
        parallel=parallel,  # type: ignore[arg-type]
    )
    one = np.zeros(single.action_space.shape or (0,), np.float32)
    many = np.zeros((sessions, *one.shape), np.float32)
    seed = [0]

    def run_single(n: int) -> float:
        t0 = time.perf_counter()
        for _ in range(n):
            if single.step(one)[2]:
                seed[0] += 1
                single.reset(seed=seed[0])
        return n / (time.perf_counter() - t0)

    def run_batch(n: int) -> float:
        t0 = time.perf_counter()
        for _ in range(n):
            batch.step(many)
        return n * sessions / (time.perf_counter() - t0)

    single.reset(seed=0)
    batch.reset(seed=0)
    run_single(100)  # warm up (compiled code loaded)
    run_batch(10)
    singles: list[float] = []
    batched: list[float] = []
    for _ in range(rounds):
        singles.append(run_single(single_steps))
        batched.append(run_batch(max(1, single_steps // sessions)))
    out: dict[str, Any] = {
        "single_steps_per_s": float(np.median(singles)),
        "batched_steps_per_s": float(np.median(batched)),
        "batched_ratio": float(np.median(np.array(batched) / np.array(singles))),
        "batched_sessions": float(sessions),
        "batched_threads": float(batch.threads),
        "load_1min": float(os.getloadavg()[0]),
    }
    single.close()
    batch.close()
    return out
