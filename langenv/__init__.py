"""LangCtrl: robots that move and speak in step with a person.

Importing the package registers the Gymnasium environment ``LangCtrl-v0``
(see :class:`langenv.env.LangCtrlEnv` for its full specification)::

    import gymnasium as gym
    import langenv  # noqa: F401

    env = gym.make("LangCtrl-v0", users="synthetic", decision_hz=25)  # 60 s sessions
"""

from __future__ import annotations

from importlib.metadata import PackageNotFoundError, version

from langenv.robot.gl import default_backend

default_backend()  # before anything imports MuJoCo: EGL on a headless Linux machine

from gymnasium.envs.registration import register, registry  # noqa: E402

__all__ = ["ENV_ID", "__version__"]

try:  # one source: pyproject.toml's version, as installed
    __version__ = version("langctrl")
except PackageNotFoundError:  # a source tree that was never installed
    __version__ = "unknown"
ENV_ID = "LangCtrl-v0"

if ENV_ID not in registry:
    register(
        id=ENV_ID,
        entry_point="langenv.env:make_env",
        vector_entry_point="langenv.batch:make_vector_env",
        # no step-counting TimeLimit: the env truncates at max_seconds (60 s) at any decision_hz
    )
