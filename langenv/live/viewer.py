"""MuJoCo's interactive viewer as the live mode's front end: you drag the handle, you see the talk.

:class:`ViewerHooks` opens the passive viewer (``mujoco.viewer.launch_passive``) on the env's arm,
and about 60 times a second: reads your mouse perturbation into the :class:`DragUser`, syncs the
picture, and overlays the phrase being said, the paces ``p`` and ``a``, cooperation, EM and your
force. Select the handle with a double-click, then hold Ctrl and drag with the right mouse button.
"""

from __future__ import annotations

import contextlib
import math
import os
import sys
import threading
import time
from typing import Any

import numpy as np

from langenv.errors import DeviceError
from langenv.live.drag import DragUser
from langenv.live.loop import LiveHooks, RealTimeLoop
from langenv.robot.camera import FORCE_SCALE, add_arrow, add_polyline

__all__ = ["ViewerHooks", "check_display"]

HELP = "to push: double-click the handle, then Ctrl + right-drag"

RENDER_NICE = 5
"""Niceness of the viewer's render thread (0 is normal, 19 the lowest priority)."""

READY_S = 3.0
"""Seconds between the window opening and the session's start."""


def _lower_priority(threads: set[threading.Thread]) -> None:
    """Let the physics and audio come first: nice the viewer's render thread (Linux: per
    thread). Drawing can wait a frame; a late tick or an underrun is what the person notices."""
    if not sys.platform.startswith("linux"):
        return
    for thread in threads:
        if thread.native_id is not None:
            with contextlib.suppress(OSError):  # not permitted: keep the default priority
                os.setpriority(os.PRIO_PROCESS, thread.native_id, RENDER_NICE)


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
        motion = env.unwrapped.motion
        self.model, self.data, self.site = motion.arm.model, motion.arm.data, motion.arm.site_id
        self.user = user
        self.status = ""
        self.path = motion.trajectory.sample(200)
        # With software OpenGL (Mesa llvmpipe) draw in the viewer's own (low-priority) thread
        # rather than in one thread per core competing with the physics; GPUs ignore this. A
        # 1024 px shadow map looks the same in a window and draws ~4x faster without a GPU.
        os.environ.setdefault("LP_NUM_THREADS", "0")
        self.model.vis.quality.shadowsize = min(int(self.model.vis.quality.shadowsize), 1024)
        before = set(threading.enumerate())
        try:
            self.handle = mujoco.viewer.launch_passive(
                self.model, self.data, show_left_ui=False, show_right_ui=False
            )
        except Exception as exc:  # GLFW and OpenGL failures come as several types
            raise DeviceError(f"MuJoCo's viewer cannot open a window: {exc}") from None
        self._threads = set(threading.enumerate()) - before
        _lower_priority(self._threads)
        cam = self.handle.cam  # from the front, as the model's "overview" camera
        cam.lookat[:] = self.path.mean(axis=0)
        cam.distance, cam.azimuth, cam.elevation = 1.1, 116.0, -27.0
        with self.handle.lock():
            add_polyline(self.handle.user_scn, self.path)
            self._n_path = self.handle.user_scn.ngeom
        # set_texts waits for the render thread to draw a frame (200 ms with software OpenGL):
        # its own thread keeps that wait out of the real-time loop.
        self._texts_now: list[tuple[Any, Any, str, str]] = []
        self._closing = threading.Event()
        self._overlay = threading.Thread(target=self._show_texts, name="overlay", daemon=True)
        self._overlay.start()

    def _show_texts(self) -> None:
        shown: list[tuple[Any, Any, str, str]] = []
        while not self._closing.wait(0.05) and self.handle.is_running():
            texts = self._texts_now
            if texts != shown:
                self.handle.set_texts(texts)
                shown = texts

    def close(self) -> None:
        """Close the window."""
        self._closing.set()
        self._overlay.join(timeout=2.0)
        self.handle.close()
        for thread in self._threads:  # let the window go before the interpreter does
            thread.join(timeout=5.0)

    def countdown(self, seconds: float = READY_S) -> None:
        """Show the arm and a countdown before the session starts: time to find the handle (and
        for the viewer to load; mouse input is ignored while it shows "LOADING")."""
        end = time.monotonic() + seconds
        while self.handle.is_running() and (left := end - time.monotonic()) > 0:
            self.handle.sync()
            self._texts_now = [
                (
                    self._mujoco.mjtFontScale.mjFONTSCALE_150,
                    self._mujoco.mjtGridPos.mjGRID_TOPLEFT,
                    "Get ready",
                    f"the session starts in {math.ceil(left)} s; {HELP}",
                )
            ]
            time.sleep(0.05)

    def running(self) -> bool:
        """Until the window is closed."""
        return bool(self.handle.is_running())

    def frame(self, loop: RealTimeLoop) -> None:
        """Read the drag, show the state."""
        if self.user is not None:
            self.user.update(self.handle.perturb, self.data)
        force = self.user.current if self.user is not None else loop.base.motion.f_user
        scene = self.handle.user_scn
        with self.handle.lock():
            scene.ngeom = self._n_path  # the path stays; the force arrow is drawn anew
            add_arrow(scene, self.data.site_xpos[self.site].copy(), force * FORCE_SCALE)
        self.handle.sync()
        self._texts_now = self._texts(loop)

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
        top_left, top_right = "Robot says", said
        if loop.sessions and self.status and base.speech.done and base.motion.motion_done:
            top_left, top_right = top_left + "\nSession", f"{said}\n{self.status}"
        left = "Paces\nPerson"
        right = (
            f"p {info.get('p', 1.0):.2f}   a {info.get('a', 1.0):.2f}   "
            f"EM {info.get('em', 0.0):+.2f} s\n"
            f"cooperation {info.get('cooperation', 1.0):.2f}   "
            f"force {float(np.linalg.norm(force)):.0f} N"
        )
        if self.user is not None:
            left, right = left + "\nYou", right + "\n" + HELP
        return [
            (mj.mjtFontScale.mjFONTSCALE_150, mj.mjtGridPos.mjGRID_TOPLEFT, top_left, top_right),
            (mj.mjtFontScale.mjFONTSCALE_150, mj.mjtGridPos.mjGRID_BOTTOMLEFT, left, right),
        ]
