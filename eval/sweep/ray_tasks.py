"""The ``ray`` backend: batches run by warmed Ray actors, on this machine or on a Ray cluster.

``address="local"`` starts a private Ray instance here (``num_cpus = workers``, no dashboard,
its files in a temporary directory) and shuts it down with :meth:`RayBackend.close`;
``"auto"`` joins the cluster this machine belongs to (``ray start --head`` / ``ray start
--address``), ``"ray://HOST:PORT"`` one reached through Ray Client.

One actor (:class:`SweepWorker`, one CPU) per CPU of the cluster: each imports what a session
uses and loads the compiled kernels once, when it starts (:func:`eval.sweep.session.warm_worker`,
about a second of CPU: what a forked process worker inherits from the driver), then runs batch
after batch (:func:`eval.sweep.session.run_batch`), two queued at a time so it never waits for
the driver. Starting Ray and warming the actors is a one-off cost, measured apart
(:attr:`RayBackend.startup_s`); what Ray adds per session is then the hand-off of a batch and its
rows, milliseconds for seconds of sessions. An actor whose process dies is started again and its
batches run again (``max_restarts``, ``max_task_retries``).

Ray is an optional dependency (``pip install -e ".[sweep]"``), imported here only.
"""

from __future__ import annotations

import shutil
import tempfile
import time
from collections import deque
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import Any

from eval.sweep.session import Batch, BatchResult, run_batch, warm_worker

__all__ = ["MAX_RETRIES", "QUEUED", "RayBackend", "SweepWorker", "import_ray"]

#: Times Ray starts an actor again whose process died (and runs its batches again).
MAX_RETRIES = 3
#: Batches given to an actor at once: one running, the next waiting in its queue.
QUEUED = 2
#: Longest temporary directory given to a local Ray (its socket paths must stay short).
_MAX_TEMP_DIR = 40


def import_ray() -> Any:
    """The ``ray`` module.

    Raises:
        DeviceError: Ray is not installed (naming the extra that installs it).
    """
    try:
        import ray
    except ImportError as exc:
        from langenv.errors import DeviceError

        raise DeviceError(
            f'--backend ray needs Ray ({exc}): pip install -e ".[sweep]" '
            "(or run with --backend processes)"
        ) from None
    return ray


class SweepWorker:
    """A Ray actor: one warmed worker process that runs batches (one CPU)."""

    def __init__(self) -> None:
        self._warm_s = warm_worker()

    def ready(self) -> float:
        """The seconds its warm-up took (calling it waits for the warm-up)."""
        return self._warm_s

    def run(self, batch: list[Any]) -> BatchResult:
        """:func:`eval.sweep.session.run_batch`."""
        return run_batch(batch)


class RayBackend:
    """Batches run by warmed Ray actors (:class:`SweepWorker`, one per CPU of the cluster).

    Args:
        workers: CPUs of the local Ray instance (``address="local"``); on a cluster its CPUs
            decide and ``workers`` is ignored.
        address: ``"local"``, ``"auto"`` or ``"ray://HOST:PORT"``.
    """

    def __init__(self, workers: int, address: str = "local") -> None:
        t0 = time.perf_counter()
        ray = import_ray()
        self._ray = ray
        self._tmp: Path | None = None
        root = str(Path(__file__).resolve().parents[2])  # the tree this code runs from
        job = ray.job_config.JobConfig(code_search_path=[root])
        if address == "local":
            # Ray's sockets live in its temporary directory, and a Unix socket's path has about
            # 100 characters: a long temporary directory (macOS's) leaves Ray its own default.
            tmp = Path(tempfile.mkdtemp(prefix="ray-"))
            self._tmp = tmp if len(str(tmp)) <= _MAX_TEMP_DIR else None
            if self._tmp is None:
                tmp.rmdir()
            ray.init(
                address="local",
                num_cpus=workers,
                include_dashboard=False,
                log_to_driver=False,
                logging_level="warning",
                configure_logging=True,
                job_config=job,
                _temp_dir=str(self._tmp) if self._tmp is not None else None,
            )
        else:
            ray.init(address=address, job_config=job, log_to_driver=False, logging_level="warning")
        self.workers = max(1, int(ray.cluster_resources().get("CPU", workers)))
        actor = ray.remote(num_cpus=1, max_restarts=MAX_RETRIES, max_task_retries=MAX_RETRIES)(
            SweepWorker
        )
        self._actors = [actor.remote() for _ in range(self.workers)]
        try:
            warm = ray.get([a.ready.remote() for a in self._actors])
        except BaseException:  # an actor could not start: no Ray left behind
            self.close()
            raise
        self.warm_s = max(warm)
        """The slowest actor's warm-up (s)."""
        self.startup_s = time.perf_counter() - t0
        """Ray started (or joined) and every actor warmed (s): the one-off cost."""

    def run(self, batches: Sequence[Batch]) -> Iterator[tuple[int, BatchResult]]:
        """Run every batch; yield ``(index, result)`` as each finishes. An actor gets its next
        batch as one finishes (:data:`QUEUED` at a time), so faster nodes take more."""
        ray = self._ray
        todo = deque(range(len(batches)))
        running: dict[Any, tuple[int, Any]] = {}

        def give(actor: Any) -> None:
            k = todo.popleft()
            running[actor.run.remote(list(batches[k]))] = (k, actor)

        for _ in range(QUEUED):
            for actor in self._actors:
                if todo:
                    give(actor)
        while running:
            done, _ = ray.wait(list(running), num_returns=1)
            for ref in done:
                k, actor = running.pop(ref)
                result = ray.get(ref)
                if todo:
                    give(actor)
                yield k, result

    def close(self) -> None:
        """Shut Ray down (the local instance with it) and remove its temporary files."""
        if self._ray.is_initialized():
            self._ray.shutdown()
        if self._tmp is not None:
            shutil.rmtree(self._tmp, ignore_errors=True)
            self._tmp = None
