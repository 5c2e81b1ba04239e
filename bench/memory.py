"""What a session of the batched env costs in memory: ``python -m bench.memory [--sessions 8,128]``.

Each size runs in a fresh process (``python -m bench.memory --one N``): ``gym.make_vec(
"LangCtrl-v0", num_envs=N)``, a reset and 50 steps with a fixed action, then its peak resident
memory (``resource.getrusage``'s ``ru_maxrss``). A session's cost is the slope between the
smallest and the largest size, ``(RSS(N_max) - RSS(N_min)) / (N_max - N_min)``: what the
process holds whatever the size (imports, compiled code, the shared caches) cancels out.
``--heap N`` also prints what the heap holds after building ``N`` sessions, by file and line
(``tracemalloc``), for finding what each session keeps.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import resource
import subprocess
import sys
from typing import Any

__all__ = ["measure_memory", "peak_rss_mib"]

_STEPS = 50


def peak_rss_mib() -> float:
    """This process's peak resident memory (MiB; Linux reports KiB, macOS bytes)."""
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return peak / (1024.0 * 1024.0) if sys.platform == "darwin" else peak / 1024.0


def _run_batch(n: int, steps: int = _STEPS) -> None:
    """Build ``n`` sessions, reset them and take ``steps`` steps."""
    import gymnasium as gym
    import numpy as np

    import langenv

    envs = gym.make_vec(langenv.ENV_ID, num_envs=n)
    envs.reset(seed=0)
    action = np.zeros(envs.action_space.shape or (0,), np.float32)
    for _ in range(steps):
        envs.step(action)
    envs.close()


def _one(n: int) -> dict[str, float]:
    """In this process: ``n`` sessions built, reset and stepped; the peak RSS."""
    _run_batch(n)
    return {"sessions": float(n), "peak_rss_mib": peak_rss_mib()}


def _heap(n: int, top: int = 25) -> None:
    """Print the ``top`` places of the heap's growth from 1 session to ``n`` (tracemalloc)."""
    import tracemalloc

    import gymnasium as gym

    import langenv

    first = gym.make_vec(langenv.ENV_ID, num_envs=1)  # imports, compiled code, caches
    tracemalloc.start(1)
    before = tracemalloc.take_snapshot()
    envs = gym.make_vec(langenv.ENV_ID, num_envs=n)
    after = tracemalloc.take_snapshot()
    for stat in after.compare_to(before, "lineno")[:top]:
        print(
            f"{stat.size_diff / n / 1024:9.1f} KiB/session  {stat.count_diff / n:8.0f} obj  "
            f"{stat.traceback[0]}"
        )
    grown = sum(s.size_diff for s in after.compare_to(before, "lineno"))
    print(f"heap (Python allocations) per session: {grown / n / 1024:.1f} KiB")
    envs.close()
    first.close()


def _machine() -> str:
    """The machine the figures come from (a benchmark says where it ran)."""
    try:
        cores = len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        cores = os.cpu_count() or 1
    return (
        f"{platform.machine()} {platform.processor() or platform.system()}, {cores} cores, "
        f"Python {platform.python_version()}, load {os.getloadavg()[0]:.2f}"
    )


def measure_memory(sessions: tuple[int, ...] = (8, 128)) -> dict[str, float]:
    """Peak RSS of a batch of each size (each in a fresh process) and the slope per session.

    Returns:
        ``batch_rss_<N>_mib`` for each size and ``batch_mib_per_session``.
    """
    sizes = sorted(set(sessions))
    if len(sizes) < 2:
        raise ValueError(f"two sizes at least, got {sessions}")
    out: dict[str, float] = {}
    for n in sizes:
        cmd = [sys.executable, "-m", "bench.memory", "--one", str(n)]
        done = subprocess.run(cmd, capture_output=True, text=True, check=True)
        out[f"batch_rss_{n}_mib"] = json.loads(done.stdout.strip().splitlines()[-1])["peak_rss_mib"]
    lo, hi = sizes[0], sizes[-1]
    out["batch_mib_per_session"] = (out[f"batch_rss_{hi}_mib"] - out[f"batch_rss_{lo}_mib"]) / (
        hi - lo
    )
    return out


def main(argv: list[str] | None = None) -> int:
    """Entry point; returns the exit status."""
    parser = argparse.ArgumentParser(prog="python -m bench.memory", description=__doc__)
    parser.add_argument("--sessions", default="8,128", help="sizes, comma-separated")
    parser.add_argument("--one", type=int, metavar="N", help=argparse.SUPPRESS)
    parser.add_argument("--heap", type=int, metavar="N", help="heap growth by line for N sessions")
    args = parser.parse_args(argv)
    if args.one is not None:
        print(json.dumps(_one(args.one)))
        return 0
    if args.heap is not None:
        _heap(args.heap)
        return 0
    sizes = tuple(int(s) for s in args.sessions.split(",") if s.strip())
    figures: dict[str, Any] = measure_memory(sizes)
    print(json.dumps({k: round(v, 2) for k, v in figures.items()}))
    print(f"machine: {_machine()}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
