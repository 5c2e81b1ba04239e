"""The robot: our UR5 MJCF, the arm with its velocity controller C, and the force sensor."""

from __future__ import annotations

# MuJoCo's OpenGL backend (EGL on headless Linux) is chosen by ``langenv/__init__.py``, which
# runs before any of its subpackages imports MuJoCo (langenv.robot.gl).
from langenv.robot.arm import UR5_JOINTS, UR5_XML, Arm
from langenv.robot.force_sensor import ForceSensor

__all__ = ["UR5_JOINTS", "UR5_XML", "Arm", "ForceSensor"]
