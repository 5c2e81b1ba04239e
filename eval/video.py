"""Session videos: the arm guiding the hand, what it says, and the robot's voice as the sound track.

``langctrl video LOG.npz --out X.mp4`` renders one from an episode log written by
``langctrl compare`` (``sessions/<policy>_<user>.npz``); ``langctrl compare --video`` writes one
per episode. Each frame shows:

* the off-screen render of the arm (MuJoCo) with the exercise path and the person's force on the
  handle as an arrow (1 cm per N), replayed from the log's joint positions and forces;
* a panel of live traces on the session's time axis: the paces ``p`` and ``a``, cooperation
  ``c`` and the estimated misalignment EM, the past bright, the future dim, with the current
  values and the motion and speech ends marked;
* the phrase being said as a caption, and the leg of the exercise the hand is in (its name,
  ``leg 2/3: back``; ``legs done`` after the last) in the caption band's corner.

The sound track is the robot's speech, rendered exactly as the session's WAV
(:func:`langenv.speech.render.render_history` with the log's phrases and audio pace), starting
at the first frame. The file is H.264 (yuv420p) + AAC in MP4 with the index at the front, so it
plays in browsers and slides; it is encoded in-process by PyAV (FFmpeg's libraries ship in its
wheel) and written atomically.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from fractions import Fraction
from functools import lru_cache
from pathlib import Path
from typing import Any

import numpy as np

from eval.episode import EpisodeLog
from eval.report import display_name
from langenv.errors import ConfigError
from langenv.files import temp_file

__all__ = [
    "DEFAULT_FPS",
    "FRAME_SIZE",
    "SceneReplay",
    "SessionFrames",
    "TracePanel",
    "session_audio",
    "write_video",
]

DEFAULT_FPS = 25
"""Frames per second of session videos."""

SCENE_SIZE = (640, 480)
"""Size of the 3-D view (width, height, px)."""

PANEL_WIDTH = 320
"""Width of the trace panel right of the 3-D view (px)."""

CAPTION_HEIGHT = 64
"""Height of the caption band below (px)."""

FRAME_SIZE = (SCENE_SIZE[0] + PANEL_WIDTH, SCENE_SIZE[1] + CAPTION_HEIGHT)
"""Size of a video frame (width, height, px): multiples of 16, as H.264 likes them."""

CRF = 23
"""x264 constant rate factor (lower: better quality, larger file)."""

PRESET = "veryfast"
"""x264 speed preset: the scene is simple, so a fast preset loses little at this rate factor."""

# Off-screen render quality: a 1024 px shadow map and no multisampling keep a software (Mesa)
# frame near 60 ms at 640 x 480 instead of ~450 ms, with shadows that look the same at this size.
_SHADOW_SIZE = 1024
_OFF_SAMPLES = 0

_BG = (22, 27, 34)
_FG = (230, 233, 237)
_DIM = (110, 118, 129)
_GRID = (48, 54, 61)
_COLORS = {
    "p": (86, 180, 233),  # Okabe-Ito sky blue
    "a": (230, 159, 0),  # orange
    "cooperation": (0, 158, 115),  # bluish green
    "em": (204, 121, 167),  # reddish purple
}


@lru_cache(maxsize=8)
def _font(size: int) -> Any:
    """DejaVu Sans (shipped with matplotlib) at ``size`` px."""
    from matplotlib import font_manager
    from PIL import ImageFont

    path = font_manager.findfont(font_manager.FontProperties(family="DejaVu Sans"))
    return ImageFont.truetype(path, size)


class SceneReplay:
    """Renders the arm at logged joint positions, with the exercise path and the person's force.

    Args:
        size: Image size (width, height, px).
        model_path: The arm's MJCF (default: our UR5); its ``nq`` must match the log's ``qpos``.
        handle_site: Site where the force acts (the arrow's tail).
        path: Exercise path to draw, shape (N, 3) (m); default: the default exercise's.

    Raises:
        ConfigError: unreadable model, unknown site, or no off-screen OpenGL backend.
    """

    def __init__(
        self,
        size: tuple[int, int] = SCENE_SIZE,
        *,
        model_path: str | Path | None = None,
        handle_site: str = "handle",
        path: np.ndarray | None = None,
    ) -> None:
        from langenv.robot import UR5_XML  # first: it picks MuJoCo's GL backend (EGL if headless)

        import mujoco  # isort: skip

        from langenv.control.trajectory import default_exercise
        from langenv.robot.camera import SceneRenderer

        xml = Path(UR5_XML if model_path is None else model_path)
        try:
            self.model = mujoco.MjModel.from_xml_path(str(xml))
        except ValueError as exc:
            raise ConfigError(f"model_path {str(xml)!r} is not a valid MJCF: {exc}") from None
        self.model.vis.quality.shadowsize = _SHADOW_SIZE
        self.model.vis.quality.offsamples = _OFF_SAMPLES
        self.data = mujoco.MjData(self.model)
        self.site = mujoco.mj_name2id(self.model, mujoco.mjtObj.mjOBJ_SITE, handle_site)
        if self.site < 0:
            raise ConfigError(f"handle_site {handle_site!r} not found in {xml}")
        self.path = default_exercise().sample(200) if path is None else np.asarray(path, float)
        try:
            self._renderer = SceneRenderer(self.model, *size)
        except Exception as exc:  # MuJoCo raises several types when no GL context can be made
            raise ConfigError(
                f"cannot render off-screen ({type(exc).__name__}: {exc}); set MUJOCO_GL=egl or "
                "osmesa before Python starts"
            ) from None
        self._mujoco = mujoco

    def render(self, qpos: np.ndarray, force: np.ndarray) -> np.ndarray:
        """The scene at joint positions ``qpos`` (nq,) with force ``force`` (3,) N; (H, W, 3)."""
        if qpos.shape != (self.model.nq,):
            raise ConfigError(
                f"qpos has {qpos.shape[0]} values but the arm model has nq = {self.model.nq}"
            )
        self.data.qpos[:] = qpos
        self._mujoco.mj_kinematics(self.model, self.data)
        self._mujoco.mj_camlight(self.model, self.data)
        return self._renderer.render(
            self.data,
            path=self.path,
            force=np.asarray(force, np.float64),
            force_at=self.data.site_xpos[self.site].copy(),
        )

    def close(self) -> None:
        """Free the GL context."""
        self._renderer.close()


@dataclass(frozen=True)
class _Plot:
    """One trace box of the panel: its traces, value range and pixel rectangle."""

    title: str
    names: tuple[str, ...]
    lo: float
    hi: float
    top: int
    height: int


class TracePanel:
    """The panel of live traces: p and a, cooperation, EM, on the session's time axis.

    The full traces are drawn once, dim and bright; a frame at time ``t`` shows the bright image
    left of the cursor and the dim one right of it, plus the current values.

    Args:
        log: The episode.
        t_end: End of the time axis (s), at least the log's last time.
        size: Panel size (width, height, px).
    """

    _MARGIN_L, _MARGIN_R = 44, 12

    def __init__(self, log: EpisodeLog, t_end: float, size: tuple[int, int]) -> None:
        from PIL import Image, ImageDraw

        self.log = log
        self.w, self.h = size
        self.t0 = float(log.t[0])
        self.t1 = max(float(t_end), self.t0 + 1e-3)
        em_hi = max(1.0, float(np.ceil(np.max(np.abs(log.em)))))
        head = 68  # header lines above the first plot's title
        box = (self.h - head - 8) // 3  # title (20 px), plot, gap (10 px)
        top = head + 20
        self.plots = (
            _Plot("paces  p  a", ("p", "a"), 0.6, 1.4, top, box - 30),
            _Plot("cooperation  c", ("cooperation",), 0.0, 1.0, top + box, box - 30),
            _Plot("EM = t_a - t_x (s)", ("em",), -em_hi, em_hi, top + 2 * box, box - 30),
        )
        dim = Image.new("RGB", size, _BG)
        bright = Image.new("RGB", size, _BG)
        for img, bright_on in ((dim, False), (bright, True)):
            draw = ImageDraw.Draw(img)
            for plot in self.plots:
                self._draw_plot(draw, plot, bright_on)
        self._dim = np.asarray(dim)
        self._bright = np.asarray(bright)

    def x_of(self, t: float) -> int:
        """Pixel column of time ``t`` (s)."""
        span = self.w - self._MARGIN_L - self._MARGIN_R
        frac = (t - self.t0) / (self.t1 - self.t0)
        return self._MARGIN_L + round(min(max(frac, 0.0), 1.0) * span)

    def _y_of(self, plot: _Plot, v: np.ndarray) -> np.ndarray:
        frac = (np.clip(v, plot.lo, plot.hi) - plot.lo) / (plot.hi - plot.lo)
        return plot.top + (1.0 - frac) * plot.height

    def _draw_plot(self, draw: Any, plot: _Plot, bright: bool) -> None:
        small = _font(12)
        x0, x1 = self._MARGIN_L, self.w - self._MARGIN_R
        y0, y1 = plot.top, plot.top + plot.height
        draw.text((x0, y0 - 18), plot.title, fill=_FG, font=small)
        draw.rectangle((x0, y0, x1, y1), outline=_GRID)
        for v in (plot.lo, plot.hi, 0.5 * (plot.lo + plot.hi)):
            y = float(self._y_of(plot, np.array([v]))[0])
            draw.line((x0, y, x1, y), fill=_GRID)
            draw.text((4, y - 7), f"{v:g}", fill=_DIM, font=small)
        for t_mark in (self.log.t_motion, self.log.t_speech):  # dotted: the two ends
            x = self.x_of(t_mark)
            for yy in range(y0, y1, 6):
                draw.line((x, yy, x, min(yy + 3, y1)), fill=_DIM)
        if plot is self.plots[0]:
            log = self.log
            draw.text(
                (8, 48),
                f"ends (dotted): motion {log.t_motion:.1f} s, speech {log.t_speech:.1f} s",
                fill=_DIM,
                font=small,
            )
        xs = np.array([self.x_of(float(t)) for t in self.log.t], dtype=np.float64)
        for name in plot.names:
            ys = self._y_of(plot, getattr(self.log, name))
            keep = np.ones(xs.size, bool)
            keep[1:] = (np.diff(xs) != 0) | (np.diff(np.round(ys)) != 0)
            color = _COLORS[name] if bright else tuple(c // 3 + 30 for c in _COLORS[name])
            draw.line(list(zip(xs[keep], ys[keep], strict=True)), fill=color, width=2)

    def frame(self, t: float, i: int) -> np.ndarray:
        """The panel at time ``t`` (s), values of sample ``i``; (H, W, 3) uint8."""
        from PIL import Image, ImageDraw

        x = self.x_of(t)
        out = self._dim.copy()
        out[:, : x + 1] = self._bright[:, : x + 1]
        img = Image.fromarray(out)
        draw = ImageDraw.Draw(img)
        log = self.log
        draw.text(
            (8, 6),
            f"{display_name(log.policy)} · user {log.user}",
            fill=_FG,
            font=_font(15),
        )
        draw.text((8, 26), f"t = {t - self.t0:.1f} s", fill=_FG, font=_font(13))
        values = {
            "p": f"p {log.p[i]:.2f}",
            "a": f"a {log.a[i]:.2f}",
            "cooperation": f"{log.cooperation[i]:.2f}",
            "em": f"{log.em[i]:+.2f} s",
        }
        for plot in self.plots:
            draw.line((x, plot.top, x, plot.top + plot.height), fill=_FG)
            right = self.w - self._MARGIN_R
            for name in reversed(plot.names):
                text = values[name]
                width = draw.textlength(text, font=_font(13))
                draw.text((right - width, plot.top - 18), text, fill=_COLORS[name], font=_font(13))
                right -= int(width) + 10
        return np.asarray(img)


class _Captions:
    """The caption band: the phrase being said (bright), the last one said in pauses (dim), and
    the motion's leg in its top-left corner (when the log has the motion's legs)."""

    def __init__(self, log: EpisodeLog, size: tuple[int, int]) -> None:
        self.log = log
        self.size = size
        self._cache: dict[tuple[int, bool, str], np.ndarray] = {}

    def frame(self, t: float) -> np.ndarray:
        said = [k for k, u in enumerate(self.log.utterances) if u.t_start <= t and not u.is_pause]
        k = said[-1] if said else -1
        speaking = k >= 0 and t < self.log.utterances[k].t_end
        key = (k, speaking, self.leg_label(t))
        if key not in self._cache:
            self._cache[key] = self._draw(k, speaking, key[2])
        return self._cache[key]

    def leg_label(self, t: float) -> str:
        """The leg the hand is in at ``t`` (``leg 2/3: back``; ``done`` after the last; empty
        without the motion's legs in the log)."""
        log = self.log
        if log.leg is None or not log.leg_names:
            return ""
        i = max(0, int(np.searchsorted(log.t, t, side="right")) - 1)
        k, n = int(log.leg[i]), len(log.leg_names)
        return f"leg {k + 1}/{n}: {log.leg_names[k]}" if k < n else "legs done"

    def _draw(self, k: int, speaking: bool, leg: str) -> np.ndarray:
        from PIL import Image, ImageDraw

        img = Image.new("RGB", self.size, _BG)
        if leg:
            ImageDraw.Draw(img).text((8, 4), leg, fill=_DIM, font=_font(13))
        if k >= 0:
            u = self.log.utterances[k]
            text = f"“{u.text or u.phrase}”"
            draw = ImageDraw.Draw(img)
            size = 24
            while size > 11 and draw.textlength(text, font=_font(size)) > self.size[0] - 24:
                size -= 1
            width = draw.textlength(text, font=_font(size))
            draw.text(
                ((self.size[0] - width) / 2, (self.size[1] - size) / 2 - 2),
                text,
                fill=_FG if speaking else _DIM,
                font=_font(size),
            )
        return np.asarray(img)


class SessionFrames:
    """The frames of a session video: 3-D view, trace panel and caption band, composed.

    Args:
        log: The episode; it must hold the scene traces (``qpos``, ``f_user``).
        t_end: End of the video (s), at least the log's last time.
        fps: Frame rate; frame ``k`` is at ``t[0] + k / fps`` and shows the last sample at or
            before that time.
        model_path: The arm's MJCF if the session did not use our UR5.

    Raises:
        ConfigError: the log has no scene traces, or no off-screen GL.
    """

    def __init__(
        self,
        log: EpisodeLog,
        t_end: float,
        *,
        fps: int = DEFAULT_FPS,
        model_path: str | Path | None = None,
    ) -> None:
        if log.qpos is None or log.f_user is None:
            raise ConfigError(
                f"episode log {log.policy}_{log.user} holds no joint positions and forces "
                "(qpos, f_user): write it again with this version of eval.compare"
            )
        self.log, self.fps = log, fps
        self._qpos, self._force = log.qpos, log.f_user
        self.scene = SceneReplay(model_path=model_path, path=log.path)
        self.panel = TracePanel(log, t_end, (PANEL_WIDTH, SCENE_SIZE[1]))
        self.captions = _Captions(log, (FRAME_SIZE[0], CAPTION_HEIGHT))
        self._frame = np.zeros((FRAME_SIZE[1], FRAME_SIZE[0], 3), np.uint8)
        self._drawn: tuple[bytes, bytes] | None = None

    def frame(self, k: int) -> np.ndarray:
        """Frame ``k``, shape (H, W, 3) uint8 (a buffer reused by the next call)."""
        log, out, (w, h) = self.log, self._frame, SCENE_SIZE
        t = float(log.t[0]) + k / self.fps
        i = max(0, int(np.searchsorted(log.t, t + 1e-9, side="right")) - 1)
        state = (self._qpos[i].tobytes(), self._force[i].tobytes())
        if state != self._drawn:  # the arm at rest (stops, after the motion) is drawn once
            out[:h, :w] = self.scene.render(self._qpos[i], self._force[i])
            self._drawn = state
        out[:h, w:] = self.panel.frame(t, i)
        out[h:] = self.captions.frame(t)
        return out

    def close(self) -> None:
        """Free the GL context."""
        self.scene.close()


def session_audio(
    log: EpisodeLog, phrase_graph: str | Path | None = None, clips: Any = None
) -> tuple[np.ndarray, int]:
    """The robot's speech in ``log``, rendered as ``eval.compare`` renders the session's WAV.

    Args:
        log: The episode (its utterances and audio pace; voiced as its ``voice`` says).
        phrase_graph: The graph spoken (a shipped key or a YAML); default: the log's own.
        clips: A :class:`~langenv.speech.audio.ClipLibrary` (default: a new one).

    Returns:
        Mono float32 audio and its sample rate (Hz).

    Raises:
        ConfigError: the log names no phrase graph and none is given, or the phrases said are
            not a path of the graph.
    """
    from langenv.speech.audio import ClipLibrary
    from langenv.speech.graph import PhraseGraph, graph_path
    from langenv.speech.render import render_history

    ref = str(phrase_graph) if phrase_graph is not None else log.phrase_graph
    if not ref:
        raise ConfigError(
            "the episode log names no phrase graph (written before the video format): pass "
            "--phrase-graph"
        )
    lib = clips if clips is not None else ClipLibrary()
    # voiced as the session was (a log of langctrl 0.5 or before: stretched, whatever the YAML
    # says today)
    graph = PhraseGraph.load(graph_path(ref), clips=lib).with_voice(log.voice)
    audio = render_history(graph, lib, log.utterances, log.t, log.a)
    return audio, lib.sr


def write_video(
    log: EpisodeLog,
    out: str | Path,
    audio: np.ndarray,
    sr: int,
    *,
    fps: int = DEFAULT_FPS,
    model_path: str | Path | None = None,
    progress: bool | None = False,
) -> Path:
    """Encode the session video of ``log`` with ``audio`` as its sound track.

    The video lasts as long as the longer of the log and the audio (the audio is padded with
    silence to the last frame); frame ``i`` shows the last sample at or before ``t[0] + i / fps``.

    Args:
        log: The episode; it must hold the scene traces (``qpos``, ``f_user``).
        out: The ``.mp4`` to write (atomically: a temp file in its directory, then renamed).
        audio: Mono audio that starts at ``log.t[0]``, shape (n,).
        sr: Its sample rate (Hz).
        fps: Frame rate.
        model_path: The arm's MJCF if the session did not use our UR5.
        progress: Show a progress bar (None: only on a terminal).

    Returns:
        The path written.

    Raises:
        ConfigError: the log has no scene traces, bad ``fps``/``audio``, or no off-screen GL.
    """
    import av
    from tqdm import tqdm

    if isinstance(fps, bool) or not isinstance(fps, int) or not 1 <= fps <= 120:
        raise ConfigError(f"fps must be an integer in [1, 120], got {fps!r}")
    audio = np.asarray(audio, np.float32).reshape(-1)
    if isinstance(sr, bool) or not isinstance(sr, int) or sr <= 0:
        raise ConfigError(f"sr must be a positive integer (Hz), got {sr!r}")
    if not np.all(np.isfinite(audio)):
        raise ConfigError("audio must be finite")
    out = Path(out)
    t0 = float(log.t[0])
    duration = max(float(log.t[-1]) - t0, audio.size / sr)
    n_frames = max(1, math.ceil(duration * fps - 1e-9))
    n_audio = round(n_frames * sr / fps)
    track = np.zeros(n_audio, np.float32)
    track[: min(audio.size, n_audio)] = audio[:n_audio]

    frames = SessionFrames(log, t0 + n_frames / fps, fps=fps, model_path=model_path)
    fd, tmp = temp_file(out.parent, prefix=f".{out.name}.", suffix=".mp4")
    os.close(fd)
    try:
        with av.open(str(tmp), "w", format="mp4", options={"movflags": "+faststart"}) as box:
            vs = box.add_stream("libx264", rate=fps, options={"crf": str(CRF), "preset": PRESET})
            vs.width, vs.height, vs.pix_fmt = FRAME_SIZE[0], FRAME_SIZE[1], "yuv420p"
            vs.time_base = Fraction(1, fps)
            aud = box.add_stream("aac", rate=sr, layout="mono")
            _mux_audio(box, aud, track, sr)
            quiet = None if progress is None else not progress
            with tqdm(total=n_frames, desc="video", unit="frame", disable=quiet) as bar:
                for k in range(n_frames):
                    vf = av.VideoFrame.from_ndarray(frames.frame(k), format="rgb24")
                    vf.pts = k
                    for packet in vs.encode(vf):
                        box.mux(packet)
                    bar.update()
            for packet in vs.encode():
                box.mux(packet)
        os.replace(tmp, out)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    finally:
        frames.close()
    return out


def _mux_audio(box: Any, stream: Any, track: np.ndarray, sr: int) -> None:
    """Encode the whole sound track (AAC) into ``box``; the muxer interleaves it with the video."""
    import av

    block = 1024
    for k in range(0, track.size, block):
        af = av.AudioFrame.from_ndarray(track[None, k : k + block], format="flt", layout="mono")
        af.sample_rate = sr
        af.pts = k
        for packet in stream.encode(af):
            box.mux(packet)
    for packet in stream.encode():
        box.mux(packet)
