"""The robot: our UR5 MJCF, the arm with its velocity controller C, and the force sensor."""

from __future__ import annotations

import os
import sys

# MuJoCo chooses its OpenGL backend when first imported: default to EGL on headless Linux.
if (
    sys.platform.startswith("linux")
    and "MUJOCO_GL" not in os.environ
    and not os.environ.get("DISPLAY")
    and not os.environ.get("WAYLAND_DISPLAY")
):
    os.environ["MUJOCO_GL"] = "egl"

from langenv.robot.arm import UR5_JOINTS, UR5_XML, Arm
from langenv.robot.force_sensor import ForceSensor

__all__ = ["UR5_JOINTS", "UR5_XML", "Arm", "ForceSensor"]
