"""What a worker does: run a batch of sessions, one row each, an error a row too.

:func:`run_batch` is the one task every backend runs (in a local process or a Ray worker). A
session that raises becomes a row with ``status = "error"``, its error (type, message and the
last frames of its traceback), its coordinates and seed, and NaN metrics; the batch goes on.
"""

from __future__ import annotations

import math
import time
import traceback
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from eval.sweep.grid import SweepSession

__all__ = ["ROW_KEYS", "Batch", "BatchResult", "run_batch", "session_row", "warm_worker"]

Batch = Sequence[SweepSession]
"""Sessions one task runs, one after the other."""

#: Keys a row has besides the episode's columns and the coordinates.
ROW_KEYS = ("session_id", "seed", "status", "error", "version")


@dataclass(frozen=True)
class BatchResult:
    """What a task returns: the rows of its batch, in order, and what running them cost.

    Attributes:
        rows: One row per session.
        wall_s: Wall time of the batch in the worker (s).
        cpu_s: CPU time of the worker process during the batch (s): unlike wall time, not
            stretched when other programs share the cores.
        thread_cpu_s: CPU time of the thread that ran the sessions (s); ``cpu_s`` less it is
            what the process's other threads took meanwhile (a Ray worker's own threads).
    """

    rows: list[dict[str, Any]]
    wall_s: float
    cpu_s: float
    thread_cpu_s: float


def warm_worker() -> float:
    """Make this process ready to run sessions: import what a session uses and load the
    compiled kernels (:func:`langenv.batch.warm.warm_up`), which is what a forked worker of
    the ``processes`` backend inherits from the driver. Returns the seconds it took (about a
    second of CPU in a fresh process)."""
    t0 = time.perf_counter()
    from eval.compare import _preload
    from langenv.batch.warm import warm_up

    _preload()
    warm_up()
    return time.perf_counter() - t0


def run_batch(sessions: Sequence[SweepSession]) -> BatchResult:
    """Run ``sessions`` one after the other in this process."""
    wall, cpu, thread = time.perf_counter(), time.process_time(), time.thread_time()
    rows = [session_row(s) for s in sessions]
    return BatchResult(
        rows,
        time.perf_counter() - wall,
        time.process_time() - cpu,
        time.thread_time() - thread,
    )


def session_row(session: SweepSession) -> dict[str, Any]:
    """Run one session; its row (never raises for an error in the episode)."""
    import langenv
    from eval.compare import EPISODE_COLUMNS, run_episode

    try:
        episode = run_episode(session.job)
        status, error = "ok", ""
    except Exception as exc:  # a failed session is a row, the others go on
        frames = traceback.format_exception(exc, limit=-4)
        error = "".join(frames)[-4000:]
        status = "error"
        episode = {c: math.nan for c in EPISODE_COLUMNS}
        episode.update(
            policy=session.coords["policy"],
            user=session.coords["user"],
            stop_limit="",
            graph="",
            graph_role="",
        )
    return {
        **episode,
        **session.coords,
        "session_id": session.session_id,
        "seed": session.seed,
        "status": status,
        "error": error,
        "version": langenv.__version__,
    }
