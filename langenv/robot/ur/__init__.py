"""A real UR through ``ur-rtde``: set-up, bridge, preflight, and a fake of the library for tests.

Importing this package needs neither ``ur-rtde`` nor MuJoCo; making a
:class:`~langenv.robot.ur.bridge.URRobot` without ``ur-rtde`` raises
:class:`~langenv.errors.DeviceError` naming the extra (``pip install -e ".[ur]"``).
``langctrl robot --host HOST --dry-run`` connects, checks and prints the plan.
"""

from __future__ import annotations

from langenv.robot.ur.bridge import INSTALL_HINT, URRobot, ur_rtde_backend
from langenv.robot.ur.config import URConfig, load_ur_config

__all__ = ["INSTALL_HINT", "URConfig", "URRobot", "load_ur_config", "ur_rtde_backend"]
