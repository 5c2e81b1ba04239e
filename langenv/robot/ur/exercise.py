"""The exercise a real UR runs, placed in its base frame: the one place the bridge reads it.

Today's exercise is :func:`~langenv.control.trajectory.default_exercise` (in our UR5 model's base
frame); ``URConfig.exercise_origin`` shifts it to where the lab puts it. When exercises become
data, only this module changes.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from langenv.control.trajectory import ArcSegment, LineSegment, Trajectory, default_exercise
from langenv.robot.ur.config import URConfig

__all__ = ["exercise_trajectory", "start_pose"]


def exercise_trajectory(config: URConfig) -> Trajectory:
    """The exercise's path in the robot's base frame (m)."""
    base = default_exercise()
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


def start_pose(config: URConfig, orientation: NDArray[np.float64]) -> NDArray[np.float64]:
    """The TCP pose (6,) at the exercise's start: its first point (m) with ``orientation``
    (rotation vector, rad: the TCP's current one, which the session holds)."""
    start = exercise_trajectory(config).position(0.0)
    return np.concatenate((start, np.asarray(orientation, dtype=np.float64)))
