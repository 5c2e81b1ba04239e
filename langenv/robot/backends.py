"""The robots LangCtrl can drive, by name: :data:`ROBOT_BACKENDS` and :func:`make_robot`.

| name | what | needs |
|---|---|---|
| ``mujoco`` | our simulated UR5 (:class:`~langenv.robot.sim_io.MujocoRobot`) | MuJoCo |
| ``ur`` | a real UR or URSim through ``ur-rtde`` (:class:`~langenv.robot.ur.bridge.URRobot`) | ``pip install -e ".[ur]"``; ``config=`` a :class:`~langenv.robot.ur.config.URConfig` |
| ``ur-fake`` | the same bridge over :mod:`~langenv.robot.ur.fake_rtde` (a simulated UR on a loopback host) | nothing |

Each backend is imported only in its own factory::

    with make_robot("ur", config=load_ur_config("configs/ur.yaml")) as robot:
        sent = robot.write_speed(xd, 0.14, robot.period)
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from types import MappingProxyType
from typing import Any

from langenv.errors import ConfigError
from langenv.robot.io import RobotIO

__all__ = ["ROBOT_BACKENDS", "make_robot"]


def _mujoco(**kwargs: Any) -> RobotIO:
    from langenv.robot.sim_io import MujocoRobot

    return MujocoRobot(**kwargs)


def _ur(**kwargs: Any) -> RobotIO:
    from langenv.robot.ur.bridge import URRobot

    return URRobot(**kwargs)


def _ur_fake(**kwargs: Any) -> RobotIO:
    from langenv.robot.ur import fake_rtde
    from langenv.robot.ur.bridge import URRobot

    return URRobot(backend=fake_rtde, **kwargs)


ROBOT_BACKENDS: Mapping[str, Callable[..., RobotIO]] = MappingProxyType(
    {"mujoco": _mujoco, "ur": _ur, "ur-fake": _ur_fake}
)
"""Backend name -> factory taking the backend's keyword arguments."""


def make_robot(name: str, **kwargs: Any) -> RobotIO:
    """The robot ``name`` (one of :data:`ROBOT_BACKENDS`) made with ``kwargs``.

    Raises:
        ConfigError: an unknown name (the known ones listed).
        DeviceError: the backend's library is missing or its robot does not answer.
    """
    factory = ROBOT_BACKENDS.get(name)
    if factory is None:
        raise ConfigError(f"unknown robot {name!r}; known: {', '.join(ROBOT_BACKENDS)}")
    return factory(**kwargs)
