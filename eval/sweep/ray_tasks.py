"""The ``ray`` backend: batches as Ray tasks, on this machine or on a Ray cluster.

``address="local"`` starts a private Ray instance here (``num_cpus = workers``, no dashboard,
its files in a temporary directory) and shuts it down with :meth:`RayBackend.close`;
``"auto"`` joins the cluster this machine belongs to (``ray start --head`` / ``ray start
--address``), ``"ray://HOST:PORT"`` one reached through Ray Client. Each task runs one batch
(:func:`eval.sweep.session.run_batch`); a worker that dies has its task run again by Ray
(``max_retries``), and at most ``4 x`` the cluster's CPUs tasks wait at once.

Ray is an optional dependency (``pip install -e ".[sweep]"``), imported here only.
"""

from __future__ import annotations

import shutil
import tempfile
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import Any

from eval.sweep.session import Batch, BatchResult, run_batch

__all__ = ["MAX_RETRIES", "RayBackend", "import_ray"]

#: Times Ray runs a task again whose worker died.
MAX_RETRIES = 3
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


class RayBackend:
    """Batches as Ray tasks.

    Args:
        workers: CPUs of the local Ray instance (``address="local"``); on a cluster its CPUs
            decide and ``workers`` is ignored.
        address: ``"local"``, ``"auto"`` or ``"ray://HOST:PORT"``.
    """

    def __init__(self, workers: int, address: str = "local") -> None:
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
        self._task = ray.remote(num_cpus=1, max_retries=MAX_RETRIES)(run_batch)

    def run(self, batches: Sequence[Batch]) -> Iterator[tuple[int, BatchResult]]:
        """Run every batch; yield ``(index, result)`` as each finishes."""
        ray = self._ray
        todo = list(range(len(batches)))[::-1]
        running: dict[Any, int] = {}
        limit = 4 * self.workers
        while todo or running:
            while todo and len(running) < limit:
                k = todo.pop()
                running[self._task.remote(list(batches[k]))] = k
            done, _ = ray.wait(list(running), num_returns=1)
            for ref in done:
                yield running.pop(ref), ray.get(ref)

    def close(self) -> None:
        """Shut Ray down (the local instance with it) and remove its temporary files."""
        if self._ray.is_initialized():
            self._ray.shutdown()
        if self._tmp is not None:
            shutil.rmtree(self._tmp, ignore_errors=True)
            self._tmp = None
