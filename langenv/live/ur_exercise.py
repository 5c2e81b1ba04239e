"""The exercise a real UR runs, placed in its base frame: the one place the bridge reads it.

An exercise is data (:mod:`langenv.exercise`): a shipped name or a YAML path, resolved with
:func:`~langenv.exercise.resolve_exercise` and checked with
:func:`~langenv.exercise.check.check_exercise` (reach, joint margins, contacts, speed, script)
before anything connects or moves (:func:`checked_exercise`). Its path is in our UR5 model's base
frame; ``URConfig.exercise_origin`` shifts it to where the lab puts it.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from langenv.control.trajectory import ArcSegment, LineSegment, Trajectory
from langenv.exercise import Exercise, resolve_exercise
from langenv.robot.ur.config import URConfig

__all__ = ["ExerciseSpec", "checked_exercise", "exercise_trajectory", "start_pose"]

ExerciseSpec = str | Path | Exercise | None
"""A shipped exercise's name, an exercise YAML, an :class:`Exercise`, or None (the study's)."""


def checked_exercise(spec: ExerciseSpec) -> Exercise:
    """The exercise ``spec``, loaded and passed through every check of
    :func:`~langenv.exercise.check.check_exercise`.

    Raises:
        ConfigError: an unknown name or a missing file; ExerciseError: a bad file or a failed
            check (the file and every problem named).
    """
    from langenv.exercise.check import check_exercise  # needs MuJoCo (the reach check)

    exercise = resolve_exercise(spec)
    check_exercise(exercise)
    return exercise


def exercise_trajectory(config: URConfig, exercise: ExerciseSpec = None) -> Trajectory:
    """The exercise's path in the robot's base frame (m): its own, shifted by
    ``config.exercise_origin``."""
    base = resolve_exercise(exercise).trajectory
    o = config.exercise_origin
    if not o.any():
        return base
    moved: list[LineSegment | ArcSegment] = []
    for seg in base.segments:
        if isinstance(seg, LineSegment):
            moved.append(LineSegment(seg.start + o, seg.end + o, seg.waypoint, seg.turn))
        else:
            moved.append(
                ArcSegment(
                    seg.center + o, seg.axis, seg.start + o, seg.angle, seg.waypoint, seg.turn
                )
            )
    return Trajectory(moved)


def start_pose(
    config: URConfig, orientation: NDArray[np.float64], exercise: ExerciseSpec = None
) -> NDArray[np.float64]:
    """The TCP pose (6,) at the exercise's start: its first point (m) with ``orientation``
    (rotation vector, rad: the TCP's current one, which the session holds)."""
    start = exercise_trajectory(config, exercise).position(0.0)
    return np.concatenate((start, np.asarray(orientation, dtype=np.float64)))
