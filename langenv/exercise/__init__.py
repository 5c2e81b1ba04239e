"""Exercises as data: a therapy exercise's path, tool turn, speed and script in a YAML file.

``python -m langenv.exercise list | check NAME|FILE | render NAME --out F.png``; the file format
is documented in :mod:`langenv.exercise.spec`, the checks in :mod:`langenv.exercise.check`.
"""

from langenv.errors import ExerciseError
from langenv.exercise.load import load_exercise
from langenv.exercise.registry import (
    DEFAULT_EXERCISE,
    SHIPPED_EXERCISES,
    exercise_path,
    resolve_exercise,
)
from langenv.exercise.spec import PROBLEM_KINDS, Exercise, Leg, Problem

__all__ = [
    "DEFAULT_EXERCISE",
    "PROBLEM_KINDS",
    "SHIPPED_EXERCISES",
    "Exercise",
    "ExerciseError",
    "Leg",
    "Problem",
    "exercise_path",
    "load_exercise",
    "resolve_exercise",
]
