"""The paper's two figures: distributions per controller (violins) and the close-up of one session.

Both draw on a :class:`matplotlib.figure.Figure` with the Agg canvas (no pyplot, no layout
engine: the margins are fixed) at :data:`DPI`, and are written atomically. The violins get a fresh
figure; the session figure's fixed part is built once per process and reused (about 40 % of its
drawing time), its session's artists replaced on every call.

* :func:`violin_figure`: cooperation ``c``, audio pace ``a``, physical pace ``p``, estimated
  misalignment EM and actual misalignment AM per controller. ``c``, ``a``, ``p`` and EM are time
  samples pooled over the sessions, taken on a uniform grid (:func:`eval.metrics.time_samples`)
  over the part of each session where they matter (``c``, ``p``: motion going on; ``a``: speech
  going on; EM: either); AM is one value per session, drawn as points over its violin.
* :func:`session_figure`: stacked panels on a shared time axis: ``c``; hand speed; ``p`` and
  ``a``; the ETCs ``t_x`` and ``t_a``; EM; and the phrases said, as labelled spans like subtitles,
  over the motion's legs (shaded bands, each leg's ``SM`` marked: :mod:`eval.legs`); vertical
  lines at the motion and speech ends, AM annotated.
"""

from __future__ import annotations

import io
import threading
from collections.abc import Mapping, Sequence
from pathlib import Path

import matplotlib
import numpy as np
from matplotlib.artist import Artist
from matplotlib.axes import Axes
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.collections import PolyCollection
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Rectangle
from matplotlib.ticker import FixedLocator, MaxNLocator, NullLocator
from PIL import Image, PngImagePlugin

from eval.episode import EpisodeLog
from eval.legs import leg_boundaries, leg_entries
from eval.metrics import A_TOLERANCE, Window, time_samples
from eval.report import AM_TOLERANCE, atomic_write, display_name
from langenv.errors import ConfigError

__all__ = [
    "DPI",
    "SESSION_SIZE",
    "VIOLIN_SIZE",
    "policy_color",
    "session_figure",
    "violin_figure",
]

DPI = 100
"""Resolution of both figures (dots per inch)."""

VIOLIN_SIZE = (15.0, 4.2)
"""Size of the violin figure (inches): 1500 x 420 px at :data:`DPI`."""

SESSION_SIZE = (11.0, 10.0)
"""Size of the close-up figure (inches): 1100 x 1000 px at :data:`DPI`."""

PACE_BOUNDS = (0.6, 1.4)
"""Pace bounds drawn as dotted lines (SPEC §1)."""

# Okabe-Ito colour-blind-safe palette; the paper's controllers get fixed colours.
_FIXED = {"ac": "#E69F00", "lc-noap": "#56B4E9", "lc": "#009E73"}
_CYCLE = ("#CC79A7", "#0072B2", "#D55E00", "#F0E442", "#000000", "#999999")
_PHRASE_COLORS = tuple(  # light ColorBrewer tones (Paired, Set3), one per phrase
    "#a6cee3 #b2df8a #fdbf6f #cab2d6 #fb9a99 #ffff99"
    " #8dd3c7 #bebada #80b1d3 #fccde5 #d9d9d9 #ccebc5".split()
)
_PNG_INFO = PngImagePlugin.PngInfo()
_PNG_INFO.add_text("Software", f"LangCtrl eval.plots (Matplotlib {matplotlib.__version__})")

_MOTION_END = "#222222"
_SPEECH_END = "#C0392B"
_LEG_SHADES = ("#EDEDED", "#DADADA")  # the motion's legs, alternately, under the phrases said
_IN_STEP, _OUT_OF_STEP = "#1B7837", "#B2182B"  # a leg's words within 1 s of the leg, or not


def policy_color(policy: str, index: int = 0) -> str:
    """Colour of a controller: fixed for AC, LC-noAP and LC, else by its position ``index``."""
    return _FIXED.get(policy, _CYCLE[index % len(_CYCLE)])


def _check_dir(path: str | Path) -> None:
    """Fail before drawing, not after, when the destination directory is missing."""
    parent = Path(path).parent
    if not parent.is_dir():
        raise FileNotFoundError(f"directory {parent} of {path} does not exist")


def _save(fig: Figure, path: str | Path) -> Path:
    """Draw ``fig`` whole and write it (:func:`_write_png`)."""
    canvas = FigureCanvasAgg(fig)
    canvas.draw()
    return _write_png(canvas, path)


def _write_png(canvas: FigureCanvasAgg, path: str | Path) -> Path:
    """The canvas as it stands, as a PNG (RGB, tagged :data:`DPI`) written atomically.

    Both figures are opaque (white figure and panel backgrounds), so the alpha channel is dropped
    as it is: a third less to encode. Pillow encodes at zlib level 1: about 3x faster than the
    default level 6, files ~20 % larger.
    """
    rgba = Image.frombuffer("RGBA", canvas.get_width_height(), canvas.buffer_rgba(), "raw")
    buf = io.BytesIO()
    rgba.convert("RGB").save(buf, format="png", compress_level=1, dpi=(DPI, DPI), pnginfo=_PNG_INFO)
    return atomic_write(path, buf.getvalue())


# --------------------------------------------------------------------------- violin figure

_PANELS: tuple[tuple[str, str, Window, str], ...] = (
    ("cooperation", "cooperation c", "motion", ""),
    ("a", "audio pace a", "speech", ""),
    ("p", "physical pace p", "motion", ""),
    ("em", "estimated misalignment EM", "either", "s"),
)


def _violin(ax: Axes, data: np.ndarray, pos: float, color: str) -> None:
    """One violin with its median and interquartile box; a bar for (near-)constant data."""
    if data.size == 0:
        ax.text(
            pos,
            0.5,
            "no data",
            ha="center",
            va="center",
            fontsize=8,
            color="0.4",
            transform=ax.get_xaxis_transform(),
        )
        return
    q1, med, q3 = np.percentile(data, [25.0, 50.0, 75.0])
    if data.size >= 2 and np.ptp(data) > 1e-9 * max(1.0, float(np.abs(data).max())):
        parts = ax.violinplot([data], positions=[pos], widths=0.8, showextrema=False, points=80)
        bodies: list[PolyCollection] = parts["bodies"]  # type: ignore[assignment]
        for body in bodies:
            body.set_facecolor(color)
            body.set_edgecolor(color)
            body.set_alpha(0.45)
    else:  # constant: a KDE is undefined, draw the value as a bar
        ax.hlines(med, pos - 0.35, pos + 0.35, colors=color, linewidth=3.0)
    ax.vlines(pos, q1, q3, colors="0.15", linewidth=4.0, zorder=3)
    ax.scatter([pos], [med], s=18, c="white", edgecolors="0.15", linewidths=0.8, zorder=4)


def violin_figure(
    logs_by_policy: Mapping[str, Sequence[EpisodeLog]], path: str | Path, *, hz: float = 50.0
) -> Path:
    """Draw the distributions of c, a, p, EM and AM per controller (the paper's summary figure).

    Args:
        logs_by_policy: Controller name -> its sessions, in the order to draw (left to right).
        path: Destination PNG (``VIOLIN_SIZE`` at ``DPI``), written atomically.
        hz: Rate (Hz) of the uniform grid the time samples are pooled on.

    Returns:
        The path written.

    Raises:
        ConfigError: if there is no controller or a controller has no session.
        FileNotFoundError: if the directory of ``path`` does not exist (checked before drawing).
    """
    _check_dir(path)
    if not logs_by_policy:
        raise ConfigError("logs_by_policy must name at least one controller")
    for name, logs in logs_by_policy.items():
        if not logs:
            raise ConfigError(f"logs_by_policy[{name!r}] has no session")
    policies = list(logs_by_policy)
    colors = [policy_color(p, k) for k, p in enumerate(policies)]
    pos = np.arange(1, len(policies) + 1, dtype=float)

    fig = Figure(figsize=VIOLIN_SIZE, dpi=DPI)
    axes = fig.subplots(
        1,
        5,
        gridspec_kw={"wspace": 0.32, "left": 0.045, "right": 0.99, "top": 0.86, "bottom": 0.22},
    )
    _draw_time_panels(axes[:4], logs_by_policy, pos, colors, hz)
    _draw_am_panel(axes[4], logs_by_policy, pos, colors)
    _style_axes(axes, logs_by_policy, pos, colors)
    fig.suptitle("Language Controller evaluation: distributions per controller", fontsize=12)
    fig.text(
        0.5,
        0.015,
        f"c, p: pooled {hz:g} Hz time samples while the motion goes on; a: while the speech goes "
        f"on (grey band: |a-1| <= {A_TOLERANCE:g}); EM: while either goes on.\n"
        f"AM: one point per session (+: motion ended first; green band: |AM| <= "
        f"{AM_TOLERANCE:g} s). Black bar: interquartile range; white dot: median.",
        ha="center",
        va="bottom",
        fontsize=8,
        color="0.3",
        linespacing=1.4,
    )
    return _save(fig, path)


def _draw_time_panels(
    axes: Sequence[Axes],
    logs_by_policy: Mapping[str, Sequence[EpisodeLog]],
    pos: np.ndarray,
    colors: Sequence[str],
    hz: float,
) -> None:
    """Violins of c, a, p and EM (pooled time samples) with their reference lines and bands."""
    for ax, (name, title, window, unit) in zip(axes, _PANELS, strict=True):
        for k, logs in enumerate(logs_by_policy.values()):
            data = np.concatenate([time_samples(log, name, window, hz) for log in logs])
            _violin(ax, data, pos[k], colors[k])
        ax.set_title(title + (f" ({unit})" if unit else ""), fontsize=10, y=1.0)
    c_ax, a_ax, p_ax, em_ax = axes
    c_ax.set_ylim(-0.02, 1.05)
    for ax in (a_ax, p_ax):
        ax.axhline(1.0, color="0.5", linestyle="--", linewidth=0.8, zorder=0)
        for b in PACE_BOUNDS:
            ax.axhline(b, color="0.6", linestyle=":", linewidth=0.8, zorder=0)
        ax.set_ylim(PACE_BOUNDS[0] - 0.05, PACE_BOUNDS[1] + 0.05)
    a_ax.axhspan(1.0 - A_TOLERANCE, 1.0 + A_TOLERANCE, color="0.9", zorder=-1, linewidth=0)
    em_ax.axhline(0.0, color="0.5", linestyle="--", linewidth=0.8, zorder=0)


def _draw_am_panel(
    am_ax: Axes,
    logs_by_policy: Mapping[str, Sequence[EpisodeLog]],
    pos: np.ndarray,
    colors: Sequence[str],
) -> None:
    """AM per session: a violin and the sessions as points, the study's tolerance as a band."""
    am_ax.axhspan(-AM_TOLERANCE, AM_TOLERANCE, color="#d8f0e4", zorder=-1, linewidth=0)
    am_ax.axhline(0.0, color="0.5", linestyle="--", linewidth=0.8, zorder=0)
    golden = (np.sqrt(5.0) - 1.0) / 2.0
    for k, logs in enumerate(logs_by_policy.values()):
        am = np.array([log.am for log in logs])
        _violin(am_ax, am, pos[k], colors[k])
        jitter = ((np.arange(am.size) * golden) % 1.0 - 0.5) * 0.3  # deterministic spread
        am_ax.scatter(
            pos[k] + jitter, am, s=12, c=colors[k], edgecolors="0.2", linewidths=0.5, zorder=5
        )
    am_ax.set_title("actual misalignment AM (s)", fontsize=10, y=1.0)
    lim = max(1.5 * AM_TOLERANCE, *(abs(log.am) for v in logs_by_policy.values() for log in v))
    am_ax.set_ylim(-1.1 * lim, 1.1 * lim)


def _style_axes(
    axes: Sequence[Axes],
    logs_by_policy: Mapping[str, Sequence[EpisodeLog]],
    pos: np.ndarray,
    colors: Sequence[str],
) -> None:
    """Controller labels in their colours, limits and grids shared by every panel."""
    labels = [f"{display_name(p)}\n(n={len(v)})" for p, v in logs_by_policy.items()]
    for ax in axes:
        ax.set_xticks(pos, labels, fontsize=9)
        for tick, color in zip(ax.get_xticklabels(), colors, strict=True):
            tick.set_color(color)
            tick.set_fontweight("bold")
        ax.set_xlim(0.4, len(labels) + 0.6)
        ax.tick_params(axis="y", labelsize=8)
        ax.grid(axis="y", color="0.92", linewidth=0.6, zorder=-2)
        ax.set_axisbelow(True)


# --------------------------------------------------------------------------- session figure


def _phrase_labels(
    ax: Axes,
    log: EpisodeLog,
    x_range: tuple[float, float],
    width_px: float,
    added: list[Artist],
) -> None:
    """The phrases said as labelled spans on ``ax``; the artists drawn are appended to ``added``."""
    colors: dict[str, str] = {}
    if not log.utterances:
        note = ax.text(
            0.5,
            0.5,
            "no phrase recorded",
            ha="center",
            va="center",
            fontsize=9,
            color="0.4",
            transform=ax.transAxes,
        )
        added.append(note)
        return
    px_per_s = width_px / (x_range[1] - x_range[0])
    char_px = 7.5 * DPI / 72.0 * 0.58  # mean glyph width of a 7.5 pt sans font
    for u in log.utterances:
        if u.is_pause:
            continue  # silence: the gap between the spans shows it
        color = colors.setdefault(u.phrase, _PHRASE_COLORS[len(colors) % len(_PHRASE_COLORS)])
        rect = Rectangle(
            (u.t_start, 0.08),
            max(u.duration, 1e-6),
            0.84,
            facecolor=color,
            edgecolor="0.35",
            linewidth=0.6,
        )
        added.append(ax.add_patch(rect))
        fit = int((u.duration * px_per_s - 4.0) / char_px)
        if fit < 2:
            continue
        text = u.text or ""
        lines = [_clip(u.phrase, fit)]
        if text:
            lines.append(_clip(text, fit))
        label = ax.text(
            u.t_start + 2.0 / px_per_s,
            0.5,
            "\n".join(lines),
            ha="left",
            va="center",
            fontsize=7.5,
            linespacing=1.15,
        )
        label.set_clip_path(rect)
        added.append(label)


def _leg_spans(ax: Axes, log: EpisodeLog, added: list[Artist]) -> None:
    """The motion's legs as shaded bands under the phrases said, each named at its top, and per
    leg boundary (:mod:`eval.legs`) where the motion entered the leg (dotted) and an arrow to
    where its words started, labelled ``SM``: green within 1 s, red beyond or never said. The
    artists drawn are appended to ``added``; nothing without the motion's legs in the log."""
    if log.leg is None or not log.leg_names:
        return
    n = len(log.leg_names)
    starts = leg_entries(log.t, log.leg, n)
    ends = [*starts[1:], log.t_motion]
    on_x = ax.get_xaxis_transform()
    sm = {b.index: b for b in leg_boundaries(log)}
    for k, name in enumerate(log.leg_names):
        a, b = float(starts[k]), float(ends[k]) if np.isfinite(ends[k]) else log.t_motion
        if not np.isfinite(a):
            continue
        added.append(ax.axvspan(a, b, color=_LEG_SHADES[k % 2], linewidth=0, zorder=0.2))
        found = sm.get(k)
        text, color = name, "0.25"
        if found is not None:
            said = np.isfinite(found.sm)
            text += f" · SM {found.sm:+.1f} s" if said else " · SM: words not said"
            color = _IN_STEP if found.in_step else _OUT_OF_STEP
            added.append(ax.axvline(a, color=color, linestyle=":", linewidth=1.2, zorder=4))
            if said and abs(found.sm) > 1e-3:
                arrow = ax.annotate(
                    "", xy=(found.t_words, 0.04), xytext=(a, 0.04), xycoords=on_x,
                    arrowprops={"arrowstyle": "->", "color": color, "linewidth": 1.2}, zorder=6,
                )  # fmt: skip
                added.append(arrow)
        label = ax.text(
            a, 0.99, f" {text}", transform=on_x, ha="left", va="top", fontsize=6.5,
            color=color, zorder=6, bbox={"facecolor": "white", "edgecolor": "none", "pad": 0.5},
        )  # fmt: skip
        added.append(label)


def _clip(text: str, n: int) -> str:
    return text if len(text) <= n else text[: max(1, n - 1)] + "…"


def session_figure(log: EpisodeLog, path: str | Path) -> Path:
    """Draw the close-up figure of one session (the paper's single-session analysis).

    The figure's fixed part (panels, reference lines, legends, ticks) is built once per process
    and reused (:class:`_SessionCanvas`), the part that never changes rendered once; what belongs
    to a session is replaced on each call, so a figure does not depend on the ones drawn before
    it.

    Args:
        log: The session.
        path: Destination PNG (``SESSION_SIZE`` at ``DPI``), written atomically.

    Returns:
        The path written.

    Raises:
        FileNotFoundError: if the directory of ``path`` does not exist (checked before drawing).
    """
    global _CANVAS
    _check_dir(path)
    with _CANVAS_LOCK:  # one figure per process: threads draw one after the other
        if _CANVAS is None:
            _CANVAS = _SessionCanvas()
        return _CANVAS.draw(log, path)


_LEFT, _RIGHT = 0.085, 0.985  # the session figure's margins (figure fraction)
_WIDTH_PX = SESSION_SIZE[0] * DPI * (_RIGHT - _LEFT)  # width of its panels (pixels)


class _SessionCanvas:
    """The session figure: its fixed artists, built once, and the session's, replaced per draw.

    Fixed: six stacked panels (``c``; hand speed; ``p`` and ``a``; the ETCs; EM; the phrases
    said), their reference lines, labels and legends, the signal lines (their data replaced), the
    end markers (moved), the legend of the ends and the title (their texts replaced). Per
    session: the EM areas, the time grid, the phrase spans and the AM arrow (removed after the
    draw).

    The part that is the same for every session (the panels' backgrounds, the axes whose range
    is fixed: ``c``, the paces, the phrases, with their ticks and labels) is rendered once into a
    background image; each draw restores it and renders the rest on top, in the order of a full
    draw (:meth:`_render`). Text is what this saves most of: Agg renders it glyph by glyph.
    """

    def __init__(self) -> None:
        self.fig = fig = Figure(figsize=SESSION_SIZE, dpi=DPI)
        self.canvas = FigureCanvasAgg(fig)
        axes = fig.subplots(
            6,
            1,
            gridspec_kw={
                "height_ratios": [1.0, 1.0, 1.2, 1.2, 1.0, 0.9],
                "hspace": 0.14,
                "left": _LEFT,
                "right": _RIGHT,
                "top": 0.935,
                "bottom": 0.055,
            },
        )
        self.axes: list[Axes] = list(axes)
        c_ax, v_ax, pace_ax, etc_ax, em_ax, say_ax = self.axes
        self.c = c_ax.plot([], [], color="#6A3D9A", linewidth=1.2)[0]
        c_ax.set_ylim(-0.03, 1.05)
        c_ax.set_ylabel("cooperation c")
        self.v = v_ax.plot([], [], color="0.2", linewidth=1.2)[0]
        v_ax.set_ylabel("hand speed (m/s)")
        for b in PACE_BOUNDS:
            pace_ax.axhline(b, color="0.6", linestyle=":", linewidth=0.8)
        pace_ax.axhline(1.0, color="0.5", linestyle="--", linewidth=0.8)
        self.p = pace_ax.plot([], [], color="#0072B2", linewidth=1.4, label="physical pace p")[0]
        self.a = pace_ax.plot([], [], color="#D55E00", linewidth=1.4, label="audio pace a")[0]
        pace_ax.set_ylim(PACE_BOUNDS[0] - 0.07, PACE_BOUNDS[1] + 0.07)
        pace_ax.set_ylabel("pace")
        pace_ax.legend(loc="lower left", fontsize=8, ncol=2, frameon=False)
        self.t_x = etc_ax.plot(
            [], [], color="#0072B2", linewidth=1.4, label="motion ETC $\\hat t_x$"
        )[0]
        self.t_a = etc_ax.plot(
            [], [], color="#D55E00", linewidth=1.4, label="speech ETC $\\hat t_a$"
        )[0]
        etc_ax.set_ylabel("ETC (s)")
        etc_ax.legend(loc="upper right", fontsize=8, ncol=2, frameon=False)
        em_ax.axhline(0.0, color="0.5", linestyle="--", linewidth=0.8)
        self.em = em_ax.plot([], [], color="0.15", linewidth=1.2, zorder=2.5)[0]
        em_ax.set_ylabel("EM (s)")
        say_ax.set_ylabel("phrase said")
        say_ax.set_xlabel("time (s)")
        say_ax.set_ylim(0.0, 1.0)
        self.ends = [
            (
                ax.axvline(0.0, color=_MOTION_END, linewidth=1.1, zorder=5),
                ax.axvline(0.0, color=_SPEECH_END, linewidth=1.1, linestyle="--", zorder=5),
            )
            for ax in self.axes
        ]
        self._style_axes()
        handles = [
            Line2D([], [], color=_MOTION_END, linewidth=1.1, label="motion end"),
            Line2D([], [], color=_SPEECH_END, linewidth=1.1, linestyle="--", label="speech end"),
        ]
        legend = fig.legend(
            handles=handles,
            loc="upper right",
            ncol=2,
            fontsize=8,
            frameon=False,
            bbox_to_anchor=(_RIGHT, 0.965),
        )
        self.end_labels = legend.get_texts()
        self.title = fig.suptitle("", fontsize=12, fontweight="bold", x=_LEFT, ha="left")
        self.session: list[Artist] = []
        self._mark_dynamic(legend)
        self.canvas.draw()  # the background: every artist not marked animated
        self.background = self.canvas.copy_from_bbox(fig.bbox)

    def _mark_dynamic(self, end_legend: Artist) -> None:
        """Mark animated every artist but the panels' backgrounds and the axes whose range is
        fixed (``c``, the paces, the phrases; the time axis of the upper panels, which has no
        ticks): what each session changes, and whatever a full draw paints over or under it."""
        c_ax, _, pace_ax, _, _, say_ax = self.axes
        fixed: set[Artist] = {c_ax.yaxis, pace_ax.yaxis, say_ax.yaxis}
        fixed.update(ax.xaxis for ax in self.axes[:-1])
        fixed.update(ax.patch for ax in self.axes)
        for ax in self.axes:
            for artist in ax.get_children():
                if artist not in fixed:
                    artist.set_animated(True)
        end_legend.set_animated(True)
        self.title.set_animated(True)

    def _render(self) -> None:
        """The background, then every animated artist in the order of a full draw."""
        self.canvas.restore_region(self.background)
        for ax in self.axes:
            ax.viewLim  # noqa: B018 -- applies any pending autoscaling, as Axes.draw does
            artists = [a for a in ax.get_children() if a.get_animated() and a.get_visible()]
            for artist in sorted(artists, key=lambda a: a.get_zorder()):
                ax.draw_artist(artist)
        for artist in sorted(self.fig.get_children(), key=lambda a: a.get_zorder()):
            if artist.get_animated() and artist.get_visible():
                self.fig.draw_artist(artist)

    def _style_axes(self) -> None:
        """Fonts, grids and locators of every panel (the time ticks are set per session)."""
        for ax in self.axes:
            ax.tick_params(labelsize=8)
            ax.yaxis.label.set_fontsize(9)
            ax.set_axisbelow(True)
            if ax is self.axes[-1]:
                ax.yaxis.set_major_locator(NullLocator())
                ax.grid(color="0.93", linewidth=0.6, axis="x")
            else:  # no time ticks (tick objects dominate drawing time), only their grid lines
                ax.xaxis.set_major_locator(NullLocator())
                ax.yaxis.set_major_locator(MaxNLocator(nbins=4))
                ax.grid(color="0.93", linewidth=0.6, axis="y")

    def draw(self, log: EpisodeLog, path: str | Path) -> Path:
        """Draw ``log`` and write it to ``path``; the session's artists are removed afterwards."""
        t = log.t
        t_hi = max(float(t[-1]), log.t_motion, log.t_speech)
        x_range = (float(t[0]), t_hi + 0.02 * (t_hi - float(t[0])))
        try:
            self._signals(log)
            self._time_axis(log, x_range)
            _phrase_labels(self.axes[-1], log, x_range, _WIDTH_PX, self.session)
            _leg_spans(self.axes[-1], log, self.session)
            self._ends(log, x_range)
            for artist in self.session:
                artist.set_animated(True)
            self._render()
            return _write_png(self.canvas, path)
        finally:
            for artist in self.session:
                artist.remove()
            self.session.clear()

    def _signals(self, log: EpisodeLog) -> None:
        """The five signal panels' data and value ranges."""
        _, v_ax, _, etc_ax, em_ax, _ = self.axes
        t = log.t
        self.c.set_data(t, log.cooperation)
        self.v.set_data(t, log.hand_speed)
        _autoscale_from_zero(v_ax)
        self.p.set_data(t, np.where(~log.motion_done, log.p, np.nan))
        self.a.set_data(t, np.where(~log.speech_done, log.a, np.nan))
        self.t_x.set_data(t, log.t_x)
        self.t_a.set_data(t, log.t_a)
        _autoscale_from_zero(etc_ax)
        tt, em = _with_zero_crossings(t, log.em)
        for part, color in ((np.maximum(em, 0.0), "#D55E00"), (np.minimum(em, 0.0), "#0072B2")):
            # One polygon per sign: fill_between(where=em >= 0, interpolate=True) covers the
            # same area, but as a polygon per run of one sign, each built by Matplotlib in
            # Python: an aligner that keeps em near 0 flips its sign thousands of times.
            area = em_ax.fill_between(tt, part, 0.0, color=color, alpha=0.25, linewidth=0)
            self.session.append(area)
        self.em.set_data(t, log.em)
        lim = max(0.5, float(np.abs(log.em).max()) * 1.1)
        em_ax.set_ylim(-lim, lim)

    def _time_axis(self, log: EpisodeLog, x_range: tuple[float, float]) -> None:
        """One time axis for all panels: limits, the bottom's ticks, the others' grid lines."""
        locator = MaxNLocator(nbins=10, steps=[1, 2, 2.5, 5, 10])
        candidates = np.asarray(locator.tick_values(*x_range))
        x_ticks = candidates[(candidates >= x_range[0]) & (candidates <= x_range[1])]
        for ax, (motion_end, speech_end) in zip(self.axes, self.ends, strict=True):
            ax.set_xlim(*x_range)
            motion_end.set_xdata([log.t_motion, log.t_motion])
            speech_end.set_xdata([log.t_speech, log.t_speech])
            if ax is self.axes[-1]:
                ax.xaxis.set_major_locator(FixedLocator(x_ticks.tolist()))
                continue
            grid = ax.vlines(
                x_ticks,
                0.0,
                1.0,
                transform=ax.get_xaxis_transform(),
                colors="0.93",
                linewidth=0.6,
                zorder=0.5,
            )
            self.session.append(grid)

    def _ends(self, log: EpisodeLog, x_range: tuple[float, float]) -> None:
        """The legend of the two ends, the AM arrow (labelled where there is room), the title."""
        say_ax = self.axes[-1]
        self.end_labels[0].set_text(f"motion end {log.t_motion:.2f} s")
        self.end_labels[1].set_text(f"speech end {log.t_speech:.2f} s")
        am = log.am
        if abs(am) > 1e-3:
            arrow = say_ax.annotate(
                "",
                xy=(log.t_speech, 0.5),
                xytext=(log.t_motion, 0.5),
                xycoords=say_ax.get_xaxis_transform(),
                arrowprops={"arrowstyle": "<->", "color": "0.1", "linewidth": 1.0},
                zorder=6,
            )
            self.session.append(arrow)
            if abs(am) * _WIDTH_PX / (x_range[1] - x_range[0]) > 70.0:  # room for a label
                label = say_ax.text(
                    (log.t_motion + log.t_speech) / 2.0,
                    0.62,
                    f"AM {am:+.2f} s",
                    transform=say_ax.get_xaxis_transform(),
                    ha="center",
                    va="bottom",
                    fontsize=8,
                    zorder=6,
                )
                self.session.append(label)
        first = "motion ended first" if am > 0 else ("speech ended first" if am < 0 else "together")
        self.title.set_text(
            f"{display_name(log.policy)} · user {log.user} · AM = {am:+.2f} s ({first}) · "
            f"return {log.ret:.2f}"
        )
        self.title.set_color(policy_color(log.policy))


_CANVAS: _SessionCanvas | None = None
_CANVAS_LOCK = threading.Lock()


def _with_zero_crossings(t: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(t, y)`` (n,) with a point ``(t_c, 0)`` inserted wherever ``y >= 0`` changes between
    two samples, ``t_c`` where the straight line between them crosses 0 (where
    ``fill_between(..., interpolate=True)`` ends a region)."""
    t = np.asarray(t, dtype=np.float64)
    y = np.asarray(y, dtype=np.float64)
    flip = np.flatnonzero((y[:-1] >= 0.0) != (y[1:] >= 0.0))
    if flip.size == 0:
        return t, y
    y0, y1 = y[flip], y[flip + 1]
    t_c = t[flip] + (t[flip + 1] - t[flip]) * (y0 / (y0 - y1))
    return np.insert(t, flip + 1, t_c), np.insert(y, flip + 1, 0.0)


def _autoscale_from_zero(ax: Axes) -> None:
    """The y range matplotlib's autoscaling gives the axes' current data, from 0 up."""
    ax.set_autoscaley_on(True)
    ax.relim()
    ax.autoscale_view(scalex=False)
    ax.set_ylim(bottom=0.0)
