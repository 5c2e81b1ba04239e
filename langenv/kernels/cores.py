"""The CPU cores this process may run on: what the batched env's threads, training's choice of
subprocesses and the evaluation's workers count with (one helper for all of them)."""

from __future__ import annotations

import os

__all__ = ["usable_cores"]


def usable_cores() -> int:
    """CPU cores this process may run on: its affinity where the OS tells it (Linux), else every
    core of the machine; at least 1."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # not on Linux
        return max(1, os.cpu_count() or 1)
