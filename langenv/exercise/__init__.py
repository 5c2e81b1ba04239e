"""Exercises as data: a therapy exercise's path, tool turn, speed and script in a YAML file.

``langctrl exercise list | check NAME|FILE | render NAME --out F.png``; the file format
is documented in :mod:`langenv.exercise.spec`, the checks in :mod:`langenv.exercise.check`, which
phrase graph each policy speaks on an exercise in :mod:`langenv.exercise.script`.
"""

from langenv.errors import ExerciseError
from langenv.exercise.load import load_exercise
from langenv.exercise.registry import (
    DEFAULT_EXERCISE,
    SHIPPED_EXERCISES,
    exercise_path,
    resolve_exercise,
)
from langenv.exercise.script import SpokenGraph, graph_label, graph_role, speak, spoken_graph
from langenv.exercise.spec import GRAPH_ROLES, PROBLEM_KINDS, Exercise, Leg, Problem

__all__ = [
    "DEFAULT_EXERCISE",
    "GRAPH_ROLES",
    "PROBLEM_KINDS",
    "SHIPPED_EXERCISES",
    "Exercise",
    "ExerciseError",
    "Leg",
    "Problem",
    "SpokenGraph",
    "exercise_path",
    "graph_label",
    "graph_role",
    "load_exercise",
    "resolve_exercise",
    "speak",
    "spoken_graph",
]
