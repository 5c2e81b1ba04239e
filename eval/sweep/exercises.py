"""The exercises a sweep may name, and how a session's exercise reaches its episode.

The names are the shipped exercises (:data:`langenv.exercise.SHIPPED_EXERCISES`); a session's
exercise reaches :class:`~eval.compare.Job` by name, which ``eval.compare`` passes to the env.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from langenv.exercise import SHIPPED_EXERCISES

__all__ = ["DEFAULT_EXERCISE", "SWEEP_EXERCISES", "job_exercise"]

DEFAULT_EXERCISE = "external_rotation"
"""The study's exercise (SPEC §2), the env's default."""

SWEEP_EXERCISES: Mapping[str, Any] = SHIPPED_EXERCISES
"""Exercise names a sweep file may list (the one place the sweep reads them)."""


def job_exercise(name: str) -> dict[str, Any]:
    """Keyword arguments of :class:`~eval.compare.Job` that select exercise ``name``."""
    assert name in SWEEP_EXERCISES, name  # checked when the sweep file was loaded
    return {"exercise": name}
