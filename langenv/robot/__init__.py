"""The robot: our UR5 MJCF, the arm with its velocity controller C, the force sensor, and the
robot-IO seam (:mod:`langenv.robot.io`) with its backends (:mod:`langenv.robot.backends`).

Importing this package is light: ``Arm`` and ``ForceSensor`` (MuJoCo) load on first use, so
``import langenv.robot.ur`` on a machine that drives a real arm never initialises MuJoCo.
"""

from __future__ import annotations

# MuJoCo's OpenGL backend (EGL on headless Linux) is chosen by ``langenv/__init__.py``, which
# runs before any of its subpackages imports MuJoCo (langenv.robot.gl).
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from langenv.robot.arm import UR5_JOINTS, UR5_XML, Arm
    from langenv.robot.force_sensor import ForceSensor

__all__ = ["UR5_JOINTS", "UR5_XML", "Arm", "ForceSensor"]

_LAZY = {
    "UR5_JOINTS": "langenv.robot.arm",
    "UR5_XML": "langenv.robot.arm",
    "Arm": "langenv.robot.arm",
    "ForceSensor": "langenv.robot.force_sensor",
}


def __getattr__(name: str) -> Any:
    """``Arm``, ``ForceSensor``, ``UR5_JOINTS``, ``UR5_XML``: imported on first use."""
    module = _LAZY.get(name)
    if module is None:
        raise AttributeError(f"module 'langenv.robot' has no attribute {name!r}")
    import importlib

    value = getattr(importlib.import_module(module), name)
    globals()[name] = value
    return value
