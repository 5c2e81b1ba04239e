"""The ``processes`` backend: batches in local worker processes (``ProcessPoolExecutor``).

The workers are forked where the platform allows, after the driver has imported what they use
and compiled the kernels (:func:`langenv.batch.warm.warm_up`), so each starts at once. A worker
that dies (killed, out of memory) breaks the pool: the pool is built again and the batches that
had not finished are run again, up to :data:`MAX_RESTARTS` times.
"""

from __future__ import annotations

import multiprocessing
import os
import sys
import threading
import time
from collections.abc import Iterator, Sequence
from concurrent.futures import Future, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool

from eval.sweep.session import Batch, BatchResult, run_batch

__all__ = ["MAX_RESTARTS", "ProcessBackend"]

#: Times the pool is rebuilt after a worker died before the sweep stops (``--resume`` goes on).
MAX_RESTARTS = 3


def _follow_parent() -> None:
    """In a worker: end this process once the driver is gone (killed with SIGKILL, say), so
    that no orphaned worker holds memory or CPU; checked every second on a daemon thread."""
    parent = os.getppid()

    def watch() -> None:
        while os.getppid() == parent:
            time.sleep(1.0)
        os._exit(1)

    threading.Thread(target=watch, name="follow-parent", daemon=True).start()


class ProcessBackend:
    """Batches in ``workers`` local processes (``workers == 1``: in this process)."""

    def __init__(self, workers: int) -> None:
        t0 = time.perf_counter()
        self.workers = workers
        self._pool: ProcessPoolExecutor | None = self._new_pool() if workers > 1 else None
        self.startup_s = time.perf_counter() - t0

    def _new_pool(self) -> ProcessPoolExecutor:
        from eval.compare import _preload

        context = multiprocessing.get_context()
        if context.get_start_method() == "fork":
            _preload()
        return ProcessPoolExecutor(
            max_workers=self.workers, mp_context=context, initializer=_follow_parent
        )

    def run(self, batches: Sequence[Batch]) -> Iterator[tuple[int, BatchResult]]:
        """Run every batch; yield ``(index, result)`` as each finishes."""
        if self.workers == 1:
            for k, batch in enumerate(batches):
                yield k, run_batch(batch)
            return
        pending = set(range(len(batches)))
        restarts = 0
        while pending:
            self._pool = self._pool or self._new_pool()
            futures: dict[Future[BatchResult], int] = {
                self._pool.submit(run_batch, batches[k]): k for k in sorted(pending)
            }
            try:
                while futures:
                    done, _ = wait(futures, return_when="FIRST_COMPLETED")
                    for future in done:
                        k = futures.pop(future)
                        result = future.result()
                        pending.discard(k)
                        yield k, result
            except BrokenProcessPool:
                restarts += 1
                self._pool.shutdown(wait=False, cancel_futures=True)
                self._pool = None
                if restarts > MAX_RESTARTS:
                    raise
                print(
                    f"langctrl sweep: a worker died; restarting the pool "
                    f"({restarts}/{MAX_RESTARTS}), {len(pending)} batches to run again",
                    file=sys.stderr,
                )

    def close(self) -> None:
        """Shut the pool down (batches not started are dropped)."""
        if self._pool is not None:
            self._pool.shutdown(wait=False, cancel_futures=True)
            self._pool = None
