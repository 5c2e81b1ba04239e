"""The violin (summary) figure and the single-session close-up: files, sizes, edge cases."""

from __future__ import annotations

import struct
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from matplotlib.image import imread

from eval.episode import EpisodeLog, Utterance
from eval.plots import DPI, SESSION_SIZE, VIOLIN_SIZE, policy_color, session_figure, violin_figure
from langenv.errors import ConfigError

WORDS = (
    "I want you to move your hand away from your body this way",
    "slide slide slide",
    "glide really smoothly",
    "and to the side here",
    "and you're done",
)


def make_log(
    policy: str,
    user: str,
    rng: np.random.Generator,
    *,
    hz: float = 100.0,
    am: float | None = None,
    speak: bool = True,
) -> EpisodeLog:
    """A plausible session: a resistance dip, paces reacting, a few phrases."""
    t_motion = 11.5 + rng.normal(0.0, 1.0)
    if am is None:
        am = {"ac": rng.normal(0.0, 2.0), "lc-noap": rng.normal(0.5, 0.4)}.get(
            policy, rng.normal(0.2, 0.2)
        )
    t_speech = max(0.5, t_motion + am)
    t = np.arange(0.0, max(t_motion, t_speech) + 0.2, 1.0 / hz)
    c = 1.0 - 0.6 * np.exp(-((t - rng.uniform(2.0, 8.0)) ** 2) / 2.0)
    fixed = policy == "ac"
    p = np.ones_like(t) if fixed else np.clip(1.0 + 0.2 * np.sin(t), 0.6, 1.4)
    a = np.ones_like(t) if fixed else np.clip(1.3 - 0.6 * (1.0 - c) - 0.3 * c, 0.6, 1.4)
    t_x, t_a = np.maximum(t_motion - t, 0.0), np.maximum(t_speech - t, 0.0)
    utterances = []
    start, k = 0.0, 0
    while speak and start < t_speech - 0.3:
        end = min(t_speech, start + rng.uniform(0.8, 3.0))
        utterances.append(Utterance(f"ph{k}", WORDS[k % len(WORDS)], start, end))
        start, k = end + 0.3, k + 1
    return EpisodeLog(
        policy,
        user,
        t,
        c,
        0.125 * c * (t < t_motion),
        p,
        a,
        t_x,
        t_a,
        t_a - t_x,
        t >= t_motion,
        t >= t_speech,
        tuple(utterances),
        t_motion,
        t_speech,
        float(-rng.uniform(5.0, 50.0)),
    )


def png_size(path: Path) -> tuple[int, int]:
    head = path.read_bytes()[:24]
    assert head[:8] == b"\x89PNG\r\n\x1a\n", "not a PNG"
    width, height = struct.unpack(">II", head[16:24])
    return width, height


def has_colour(path: Path, hex_colour: str, min_pixels: int = 40, tol: float = 0.02) -> bool:
    """Whether at least ``min_pixels`` pixels of the PNG have (nearly) this colour.

    The count keeps anti-aliased edges of other colours (which pass through many shades) out.
    """
    img = imread(path)[..., :3]
    rgb = np.array([int(hex_colour[i : i + 2], 16) / 255.0 for i in (1, 3, 5)])
    return int((np.abs(img - rgb).max(axis=-1) < tol).sum()) >= min_pixels


def check_png(path: Path, size: tuple[float, float]) -> None:
    from PIL import Image

    assert path.is_file()
    assert png_size(path) == (round(size[0] * DPI), round(size[1] * DPI))
    with Image.open(path) as img:  # tagged with its resolution, for documents that place it
        assert tuple(round(v) for v in img.info["dpi"]) == (DPI, DPI)
    assert 20_000 < path.stat().st_size < 2_000_000
    assert [p.name for p in path.parent.iterdir() if p.name.endswith(".tmp")] == []


@pytest.mark.parametrize(
    ("case", "am", "speak", "hz"),
    [
        ("motion-first", 0.8, True, 100.0),
        ("speech-first", -2.5, True, 25.0),
        ("no-phrases", 0.3, False, 500.0),
    ],
)
def test_session_figure(tmp_path: Path, case: str, am: float, speak: bool, hz: float) -> None:
    log = make_log("lc", case, np.random.default_rng(3), hz=hz, am=am, speak=speak)
    assert (log.am < 0) == (am < 0) and bool(log.utterances) == speak
    path = session_figure(log, tmp_path / f"lc_{case}.png")
    check_png(path, SESSION_SIZE)
    # the first phrase's span is drawn in the first phrase colour, only when there are phrases
    assert has_colour(path, "#a6cee3", min_pixels=2000) == speak
    assert has_colour(path, policy_color("lc"))  # the title


def test_session_figure_keeps_nothing_of_the_previous_session(tmp_path: Path) -> None:
    """The reused figure draws a session the same whatever was drawn before it."""
    rng = np.random.default_rng(5)
    first = make_log("lc", "a", rng, hz=100.0, am=1.5, speak=True)
    other = make_log("ac", "b", rng, hz=500.0, am=-3.0, speak=False)
    before = session_figure(first, tmp_path / "before.png").read_bytes()
    session_figure(other, tmp_path / "other.png")
    after = session_figure(first, tmp_path / "after.png").read_bytes()
    assert after == before
    assert (tmp_path / "other.png").read_bytes() != before


@pytest.mark.parametrize("policy", ["lc", "ac"])
def test_session_figure_is_the_full_draw(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, policy: str
) -> None:
    """Rendering only the animated artists over the stored background gives, pixel for pixel,
    the figure a full draw of every artist gives."""
    from eval import plots

    def full_draw(self: plots._SessionCanvas) -> None:
        animated = self.fig.findobj(lambda a: a.get_animated())
        assert len(animated) > 20  # the fast path has something to leave out
        for artist in animated:
            artist.set_animated(False)
        try:
            self.canvas.draw()
        finally:
            for artist in animated:
                artist.set_animated(True)

    log = make_log(policy, "u", np.random.default_rng(8), hz=500.0, am=1.2, speak=True)
    fast = imread(session_figure(log, tmp_path / "fast.png"))
    monkeypatch.setattr(plots._SessionCanvas, "_render", full_draw)
    full = imread(session_figure(log, tmp_path / "full.png"))
    assert fast.shape == full.shape and np.array_equal(fast, full)


def test_violin_figure(tmp_path: Path) -> None:
    rng = np.random.default_rng(0)
    logs = {p: [make_log(p, f"s{k}", rng) for k in range(6)] for p in ("ac", "lc-noap", "lc")}
    logs["ppo"] = [make_log("ppo", "s0", rng, hz=25.0)]  # a single session still draws
    path = violin_figure(logs, tmp_path / "summary.png")
    check_png(path, VIOLIN_SIZE)
    for k, p in enumerate(logs):
        assert has_colour(path, policy_color(p, k)), p


def test_violin_figure_rejects_empty_input(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match="logs_by_policy"):
        violin_figure({}, tmp_path / "x.png")
    with pytest.raises(ConfigError, match="lc"):
        violin_figure({"lc": []}, tmp_path / "x.png")
    assert list(tmp_path.iterdir()) == []


def test_failed_write_leaves_nothing(tmp_path: Path) -> None:
    log = make_log("lc", "u", np.random.default_rng(1))
    with pytest.raises(FileNotFoundError):
        session_figure(log, tmp_path / "missing" / "x.png")
    assert list(tmp_path.iterdir()) == []


def test_policy_colours_are_distinct() -> None:
    colours = [policy_color(p, k) for k, p in enumerate(("ac", "lc-noap", "lc", "ppo", "x"))]
    assert len(set(colours)) == len(colours)


@pytest.mark.parametrize("seed", range(4))
def test_em_area_is_fill_betweens_where_interpolated(seed: int) -> None:
    """The EM panel's two one-polygon fills (zero crossings inserted) cover what
    ``fill_between(where=em >= 0 / em < 0, interpolate=True)`` covers, sign by sign."""
    from matplotlib.figure import Figure

    from eval.plots import _with_zero_crossings

    rng = np.random.default_rng(seed)
    t = np.cumsum(rng.uniform(0.001, 0.05, 400))
    em = np.cumsum(rng.normal(0.0, 0.05, 400)) * rng.choice([0.0, 1.0], 400, p=[0.1, 0.9])
    ax = Figure().add_subplot()

    def area(collection: Any) -> float:
        total = 0.0
        for path in collection.get_paths():
            x, y = path.vertices[:, 0], path.vertices[:, 1]
            total += 0.5 * abs(float(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1))))
        return total

    tt, yy = _with_zero_crossings(t, em)
    assert np.all(np.diff(tt) >= 0.0) and tt.size - t.size == int(
        np.count_nonzero((em[:-1] >= 0) != (em[1:] >= 0))
    )
    for where, part in ((em >= 0, np.maximum(yy, 0.0)), (em < 0, np.minimum(yy, 0.0))):
        expected = area(ax.fill_between(t, em, 0.0, where=where, interpolate=True))
        assert area(ax.fill_between(tt, part, 0.0)) == pytest.approx(expected, rel=1e-9)
