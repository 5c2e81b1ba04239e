"""Training across worlds: the split of exercises and users (:class:`WorldSplit`, ``split.py``)
and the env that draws a world per episode (:class:`WorldEnv`, ``env.py``)."""

from langenv.worlds.env import WorldEnv
from langenv.worlds.split import ROLES, WorldSplit

__all__ = ["ROLES", "WorldEnv", "WorldSplit"]
