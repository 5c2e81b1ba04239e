"""Where a sweep's batches run: a small interface, and the backends by name.

A backend takes batches of sessions and yields each batch's rows as it finishes (in any order:
the rows carry their ids, and nothing depends on which worker ran what). ``processes`` runs them
in local worker processes; ``ray`` as Ray tasks, on this machine or a cluster. Only the ``ray``
backend imports ``ray``, and only when it is built.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator, Mapping, Sequence
from types import MappingProxyType
from typing import Protocol, runtime_checkable

from eval.sweep.session import Batch, BatchResult

__all__ = ["SWEEP_BACKENDS", "Backend", "Batch", "default_backend", "make_backend"]


@runtime_checkable
class Backend(Protocol):
    """Runs batches of sessions (:func:`eval.sweep.session.run_batch`) somewhere.

    Attributes:
        workers: Sessions it runs at once (local processes, or the cluster's CPUs).
        startup_s: Seconds its construction took: the workers started and ready (Ray: Ray
            started or joined, every actor warmed), a one-off cost apart from the sessions'.
    """

    workers: int
    startup_s: float

    def run(self, batches: Sequence[Batch]) -> Iterator[tuple[int, BatchResult]]:
        """Run every batch; yield ``(index into batches, its result)`` as each finishes."""
        ...

    def close(self) -> None:
        """Release the workers (and a Ray instance this backend started)."""
        ...


def _processes(workers: int, address: str) -> Backend:
    from eval.sweep.processes import ProcessBackend

    return ProcessBackend(workers)


def _ray(workers: int, address: str) -> Backend:
    from eval.sweep.ray_tasks import RayBackend

    return RayBackend(workers, address)


#: Backends by name: ``--backend NAME``.
SWEEP_BACKENDS: Mapping[str, Callable[[int, str], Backend]] = MappingProxyType(
    {"processes": _processes, "ray": _ray}
)


def default_backend() -> str:
    """``"ray"`` where Ray can be imported, else ``"processes"``."""
    import importlib.util

    return "ray" if importlib.util.find_spec("ray") is not None else "processes"


def make_backend(name: str, workers: int, address: str = "local") -> Backend:
    """The backend ``name`` with ``workers`` workers (``address``: Ray's, see ``--address``).

    Raises:
        ConfigError: unknown name (listing the known ones).
        DeviceError: ``ray`` without Ray installed (naming the extra to install).
    """
    from langenv.errors import ConfigError

    factory = SWEEP_BACKENDS.get(name)
    if factory is None:
        raise ConfigError(f"unknown backend {name!r}; known: {', '.join(SWEEP_BACKENDS)}")
    return factory(workers, address)
