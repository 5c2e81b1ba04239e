"""The robot: our UR5 MJCF, the arm with its velocity controller C, and the force sensor."""

from __future__ import annotations

from langenv.robot.gl import default_backend

# MuJoCo chooses its OpenGL backend when first imported: default to EGL on headless Linux
# (``import langenv`` did so already; this keeps ``import langenv.robot`` alone right too).
default_backend()

from langenv.robot.arm import UR5_JOINTS, UR5_XML, Arm
from langenv.robot.force_sensor import ForceSensor

__all__ = ["UR5_JOINTS", "UR5_XML", "Arm", "ForceSensor"]
