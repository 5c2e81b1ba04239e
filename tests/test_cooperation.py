"""Cooperation filter (SPEC §1) and its inversion for replay (SPEC §3)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from langenv.control.cooperation import CooperationFilter, force_for_cooperation
from langenv.errors import ConfigError

SESSIONS = Path(__file__).parents[2] / "shared" / "sessions"
DT = 0.002


def _replay(t: np.ndarray, c: np.ndarray, force: np.ndarray, dt: float = DT) -> float:
    """Feed the force (linearly interpolated, at 1/dt) to the filter; RMSE against c."""
    grid = np.arange(t[0], t[-1], dt)
    filt = CooperationFilter()
    filt.reset(1.0 - float(c[0]))
    out = filt.run(np.interp(grid, t, force), dt)
    return float(np.sqrt(np.mean((np.interp(grid + dt, t, c) - out) ** 2)))


def test_defaults_and_initial_state() -> None:
    f = CooperationFilter()
    assert (f.alpha, f.f_max, f.r, f.c) == (0.1, 15.0, 0.0, 1.0)
    assert f.rate == pytest.approx(math.log(10.0))


@pytest.mark.parametrize("f_mag", [0.0, 3.0, 7.5, 12.0, 15.0, 40.0])
def test_steady_state(f_mag: float) -> None:
    f = CooperationFilter()
    for _ in range(10_000):  # 20 s, i.e. 46 time constants
        c = f.update(f_mag, DT)
    assert c == pytest.approx(1.0 - min(f_mag, 15.0) / 15.0, abs=1e-9)


@pytest.mark.parametrize("dt", [0.002, 0.01, 0.25])
def test_step_response_is_exact_for_any_dt(dt: float) -> None:
    """r(t) = u (1 - alpha^t) for a force step: after 1 s, r = 0.9 u (alpha = 0.1)."""
    f = CooperationFilter()
    n = round(1.0 / dt)
    for _ in range(n):
        f.update(9.0, dt)
    assert f.r == pytest.approx(0.6 * 0.9, rel=1e-9)
    assert f.c == pytest.approx(1.0 - 0.54, rel=1e-9)
    # and it decays back with the same factor
    for _ in range(n):
        f.update(0.0, dt)
    assert f.r == pytest.approx(0.054, rel=1e-9)


def test_reset_and_run() -> None:
    f = CooperationFilter(alpha=0.2, f_max=10.0)
    out = f.run(np.full(100, 20.0), 0.01)
    assert out.shape == (100,) and np.all(np.diff(out) < 0)
    f.reset()
    assert (f.r, f.c) == (0.0, 1.0)
    f.reset(0.3)
    assert f.c == pytest.approx(0.7)
    with pytest.raises(ConfigError, match="r"):
        f.reset(1.5)


@pytest.mark.parametrize(
    ("kwargs", "name"),
    [
        ({"alpha": 0.0}, "alpha"),
        ({"alpha": 1.0}, "alpha"),
        ({"alpha": math.nan}, "alpha"),
        ({"f_max": 0.0}, "f_max"),
        ({"f_max": -3.0}, "f_max"),
    ],
)
def test_filter_validation(kwargs: dict[str, float], name: str) -> None:
    with pytest.raises(ConfigError, match=name):
        CooperationFilter(**kwargs)


@pytest.mark.parametrize(
    ("f_mag", "dt", "name"),
    [(-1.0, DT, "f_mag"), (math.nan, DT, "f_mag"), (math.inf, DT, "f_mag"), (1.0, 0.0, "dt")],
)
def test_update_validation(f_mag: float, dt: float, name: str) -> None:
    with pytest.raises(ConfigError, match=name):
        CooperationFilter().update(f_mag, dt)


def test_inversion_validation() -> None:
    t = np.linspace(0, 1, 10)
    with pytest.raises(ConfigError, match="equal length"):
        force_for_cooperation(t, np.ones(9))
    with pytest.raises(ConfigError, match="increasing"):
        force_for_cooperation(t[::-1], np.ones(10))
    with pytest.raises(ConfigError, match="c must be finite"):
        force_for_cooperation(t, np.full(10, np.nan))
    with pytest.raises(ConfigError, match="alpha"):
        force_for_cooperation(t, np.ones(10), alpha=2.0)
    with pytest.raises(ConfigError, match="smooth"):
        force_for_cooperation(t, np.ones(10), smooth=-1.0)


def test_inversion_recovers_a_known_force() -> None:
    """Filter a smooth force, invert the resulting c: the force comes back."""
    t = np.arange(0.0, 12.0, 0.02)
    force = 6.0 + 5.0 * np.sin(0.8 * t) + 2.0 * np.sin(2.3 * t + 1.0)
    filt = CooperationFilter()
    grid = np.arange(0.0, 12.0, DT)
    c_grid = filt.run(np.interp(grid, t, force), DT)
    c = np.interp(t, grid + DT, c_grid)
    est = force_for_cooperation(t, c, smooth=None)
    inner = slice(5, -5)
    np.testing.assert_allclose(est[inner], force[inner], atol=0.05)


@settings(max_examples=30, deadline=None)
@given(
    centers=st.lists(st.floats(0.5, 11.5), min_size=1, max_size=4),
    heights=st.lists(st.floats(1.0, 20.0), min_size=4, max_size=4),
    widths=st.lists(st.floats(0.3, 3.0), min_size=4, max_size=4),
)
def test_inversion_round_trip_on_synthetic_traces(
    centers: list[float], heights: list[float], widths: list[float]
) -> None:
    """A c(t) trace the filter can produce (resistance episodes, 50 Hz like the recordings):
    inverted, then replayed through the filter, it comes back with RMSE <= 0.01."""
    t_fine = np.arange(0.0, 12.0, DT)
    force_fine = np.zeros_like(t_fine)
    for m, h, w in zip(centers, heights, widths, strict=False):
        inside = np.abs(t_fine - m) < w
        force_fine[inside] += h * 0.5 * (1.0 + np.cos(np.pi * (t_fine[inside] - m) / w))
    c_fine = CooperationFilter().run(force_fine, DT)
    t = np.arange(0.0, 11.9, 0.02)
    c = np.interp(t, t_fine + DT, c_fine)
    force = force_for_cooperation(t, c)
    assert np.all((force >= 0.0) & (force <= 15.0))
    assert _replay(t, c, force) <= 0.01


def test_inversion_round_trip_on_recorded_sessions() -> None:
    files = sorted(SESSIONS.glob("*.csv"))
    if not files:
        pytest.skip(f"no recorded sessions in {SESSIONS}")
    worst = 0.0
    for path in files:
        data = np.genfromtxt(path, delimiter=",", names=True)
        t, c = np.asarray(data["t"]), np.asarray(data["cooperation"])
        force = force_for_cooperation(t, c)
        worst = max(worst, _replay(t, c, force))
    assert worst <= 0.05
