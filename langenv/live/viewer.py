"""MuJoCo's interactive viewer as the live mode's front end: you drag the handle, you see the talk.

:class:`ViewerHooks` opens the passive viewer (``mujoco.viewer.launch_passive``) on the env's arm,
and about 60 times a second: reads your mouse perturbation into the :class:`DragUser`, syncs the
picture, and overlays the phrase being said, the paces ``p`` and ``a``, cooperation, EM and your
force. Select the handle with a double-click, then hold Ctrl and drag with the right mouse button.
"""

from __future__ import annotations

import os
import sys
from typing import Any

import numpy as np

from langenv.errors import DeviceError
from langenv.live.drag import DragUser
from langenv.live.loop import LiveHooks, RealTimeLoop

__all__ = ["ViewerHooks", "check_display"]

HELP = "double-click the handle, then Ctrl + right-drag to push or hold it"


def check_display() -> None:
    """Raise :class:`DeviceError` when no window can be opened (no X11/Wayland display)."""
    if sys.platform.startswith("linux") and not (
        os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")
    ):
        raise DeviceError(
            "no display for the viewer (DISPLAY is not set); run with --headless --seconds N "
            "--audio-out X.wav, or start a virtual display (xvfb-run)"
        )


class ViewerHooks(LiveHooks):
    """The passive viewer on the env's arm, with the user (if a :class:`DragUser`) fed from it.

    Args:
        env: The env (its ``unwrapped.motion.arm`` model and data are shown).
        user: The drag user to feed, or None when another user model pushes.

    Raises:
        DeviceError: no display, or the viewer (GLFW/OpenGL) cannot open.
    """

    def __init__(self, env: Any, user: DragUser | None) -> None:
        check_display()
        try:
            import mujoco.viewer
        except (ImportError, RuntimeError) as exc:
            raise DeviceError(f"MuJoCo's viewer cannot start: {exc}") from None
        self._mujoco = mujoco
        arm = env.unwrapped.motion.arm
        self.model, self.data = arm.model, arm.data
        self.user = user
        self.status = ""
        try:
            self.handle = mujoco.viewer.launch_passive(
                self.model, self.data, show_left_ui=False, show_right_ui=False
            )
        except Exception as exc:  # GLFW and OpenGL failures come as several types
            raise DeviceError(f"MuJoCo's viewer cannot open a window: {exc}") from None

    def running(self) -> bool:
        """Until the window is closed."""
        return bool(self.handle.is_running())

    def frame(self, loop: RealTimeLoop) -> None:
        """Read the drag, show the state."""
        if self.user is not None:
            self.user.update(self.handle.perturb, self.data)
        self.handle.sync()
        self.handle.set_texts(self._texts(loop))

    def session_end(self, loop: RealTimeLoop, info: dict[str, Any]) -> None:
        """Say how the session ended until the next one starts."""
        am = info.get("am")
        self.status = f"session over: AM {am:+.2f} s" if am is not None else "session over"

    def _texts(self, loop: RealTimeLoop) -> list[tuple[Any, Any, str, str]]:
        mj = self._mujoco
        info, base = loop.info, loop.base
        phrase = base.speech.phrase
        said = ""
        if phrase is not None and not base.speech.in_pause:
            said = base.graph.phrases[phrase].text or phrase
        force = self.user.current if self.user is not None else base.motion.f_user
        values = (
            f"p {info.get('p', 1.0):.2f}   a {info.get('a', 1.0):.2f}   "
            f"cooperation {info.get('cooperation', 1.0):.2f}   EM {info.get('em', 0.0):+.2f} s   "
            f"your force {float(np.linalg.norm(force)):.0f} N"
        )
        if loop.sessions and self.status and info.get("am") is not None:
            values += f"   |   {self.status}"
        return [
            (mj.mjtFontScale.mjFONTSCALE_150, mj.mjtGridPos.mjGRID_TOPLEFT, "Robot says", said),
            (mj.mjtFontScale.mjFONTSCALE_150, mj.mjtGridPos.mjGRID_BOTTOMLEFT, "Paces", values),
            (mj.mjtFontScale.mjFONTSCALE_100, mj.mjtGridPos.mjGRID_TOPRIGHT, "", HELP),
        ]
