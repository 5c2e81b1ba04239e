"""The exercises a sweep may name, and how a session's exercise reaches its episode.

Today the env runs the study's exercise only (``external_rotation``). When the exercise registry
lands (``langenv.exercise``), ``SWEEP_EXERCISES`` becomes ``SHIPPED_EXERCISES`` and
:func:`job_exercise` passes the name on (``{"exercise": name}``): nothing else changes.
"""

from __future__ import annotations

from collections.abc import Mapping
from types import MappingProxyType
from typing import Any

__all__ = ["DEFAULT_EXERCISE", "SWEEP_EXERCISES", "job_exercise"]

DEFAULT_EXERCISE = "external_rotation"
"""The study's exercise (SPEC §2), the env's default."""

SWEEP_EXERCISES: Mapping[str, Any] = MappingProxyType({DEFAULT_EXERCISE: None})
"""Exercise names a sweep file may list (the one place the sweep reads them)."""


def job_exercise(name: str) -> dict[str, Any]:
    """Keyword arguments of :class:`~eval.compare.Job` that select exercise ``name``."""
    assert name in SWEEP_EXERCISES, name  # checked when the sweep file was loaded
    return {}
