"""MuJoCo's OpenGL backend: EGL by default on a headless Linux machine, whatever the import order.

MuJoCo reads ``MUJOCO_GL`` once, when it is first imported, and without it picks GLFW, which
needs a display. :func:`default_backend` sets ``MUJOCO_GL=egl`` on Linux when neither the
variable nor a display (``DISPLAY``, ``WAYLAND_DISPLAY``) is there; ``import langenv`` calls it
before anything imports MuJoCo. Where MuJoCo was imported earlier all the same (a user's
``import mujoco`` first), :func:`ensure_headless_context` makes MuJoCo's off-screen renderer use
an EGL context when it would otherwise try GLFW without a display: call it before making a
``mujoco.Renderer`` (:class:`langenv.robot.camera.SceneRenderer` does). A ``MUJOCO_GL`` the user
set is never overridden.
"""

from __future__ import annotations

import os
import sys

__all__ = ["default_backend", "ensure_headless_context", "headless"]


def headless() -> bool:
    """Whether this is Linux without a display and without a ``MUJOCO_GL`` choice."""
    return (
        sys.platform.startswith("linux")
        and "MUJOCO_GL" not in os.environ
        and not os.environ.get("DISPLAY")
        and not os.environ.get("WAYLAND_DISPLAY")
    )


def default_backend() -> None:
    """Set ``MUJOCO_GL=egl`` on a headless Linux machine (before MuJoCo is imported)."""
    if headless():
        os.environ["MUJOCO_GL"] = "egl"


def ensure_headless_context() -> None:
    """Let MuJoCo's renderer make EGL contexts if it chose GLFW on a machine without a display.

    Only when MuJoCo was imported while ``MUJOCO_GL`` was unset (it then chose GLFW) and there
    is still no display; the choice is MuJoCo's module-level ``GLContext``, the class its
    ``Renderer`` instantiates. Nothing happens where EGL cannot be loaded (the renderer then
    fails with MuJoCo's own message, as before).
    """
    if not sys.platform.startswith("linux") or os.environ.get("DISPLAY"):
        return
    if os.environ.get("WAYLAND_DISPLAY"):
        return
    try:
        from mujoco.rendering.classic import gl_context
    except ImportError:  # another MuJoCo layout: leave it alone
        return
    chosen = getattr(gl_context, "_MUJOCO_GL", None)
    if chosen not in ("", "glfw", "enable", "enabled", "on", "true", "1"):
        return  # the user chose a backend (egl, osmesa, glx...)
    if os.environ.get("MUJOCO_GL", "egl").lower() not in ("egl", ""):
        return
    try:
        from mujoco.egl import GLContext
    except (ImportError, OSError, AttributeError):
        return
    gl_context.GLContext = GLContext
