"""Replay users: the force that reproduces a recorded cooperation trace (SPEC §3).

The cooperation filter (SPEC §1) is ``r <- alpha^dt r + (1 - alpha^dt) min(|F~|, F_max)/F_max``,
``c = 1 - r``, whose continuous form ``dr/dt = ln(1/alpha) (min(|F~|, F_max)/F_max - r)`` inverts to

    |F~|(t) = F_max (r + (dr/dt) / ln(1/alpha)),    r = 1 - c (smoothed first).

``|F~|`` is the force after the sensor's soft deadband, ``|F~| = max(0, |F| - deadband)``, so the
person pushes with ``|F| = |F~| + deadband`` whenever ``|F~| > 0`` (and not at all otherwise).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from langenv.errors import ConfigError
from langenv.users.base import (
    DEFAULT_ALPHA,
    DEFAULT_DEADBAND,
    DEFAULT_F_MAX,
    against_motion,
    sample_table,
    sample_table_array,
)
from langenv.users.session_csv import Session, load_session
from langenv.validation import MAX_SESSION_S

__all__ = ["ReplayUser", "invert_cooperation"]

_MIN_SPLINE_POINTS = 5
_MAX_GRID_DT = 0.001  # s: finest grid step at the longest session
_MAX_GRID = MAX_SESSION_S / _MAX_GRID_DT


def _check_positive(name: str, value: float, owner: str) -> float:
    value = float(value)
    if not (math.isfinite(value) and value > 0.0):
        raise ConfigError(f"{owner}: {name} must be finite and > 0, got {value!r}")
    return value


def invert_cooperation(
    t: np.ndarray,
    cooperation: np.ndarray,
    *,
    alpha: float = DEFAULT_ALPHA,
    f_max: float = DEFAULT_F_MAX,
    dt: float = 0.002,
    smoothing: float = 0.05,
    floor: float = 0.05,
) -> tuple[np.ndarray, np.ndarray]:
    """Post-deadband force magnitude that makes the cooperation filter output ``cooperation``.

    The trace is smoothed with a cubic smoothing spline (``scipy``'s ``make_smoothing_spline``,
    penalty ``lam = smoothing^4 / mean sample spacing``, so ``smoothing`` is roughly the time scale
    below which wiggles are smoothed out, whatever the sampling rate; piecewise linear below 5
    samples), then inverted on a uniform grid from 0 to ``t[-1]``. The result is clipped to
    ``[0, f_max]``: the filter saturates at ``f_max`` and cannot decay faster than with no force.
    Forces below ``floor`` are then set to 0: that is inversion ripple where the person does not
    resist, and replayed, each would become a deadband-sized push that slows the hand. Before
    the first sample (``t[0] > 0``) a constant force brings the filter from rest (``c = 1``) to
    ``cooperation[0]`` at ``t[0]`` (as close as ``f_max`` allows).

    Args:
        t: Sample times (n,), s, strictly increasing, ``t[0] >= 0``.
        cooperation: Cooperation samples (n,) in [0, 1].
        alpha: Filter decay factor (per second), in (0, 1).
        f_max: Filter force scale (N), > 0.
        dt: Grid step (s), > 0.
        smoothing: Smoothing time scale (s), > 0. 0.05 s reproduces the study's 50 Hz traces
            within 0.004 RMSE while keeping the force free of digitisation wiggles.
        floor: Smallest post-deadband force (N) kept, >= 0 (``floor / f_max`` bounds the
            cooperation error it causes).

    Returns:
        ``(grid, f_tilde)``: grid times (m,), s, ``grid[k] = k * dt`` up to ``t[-1]``; and the
        post-deadband force magnitude (m,), N, in ``[0, f_max]``.

    Raises:
        ConfigError: on a bad argument (names it), or a grid of more than 600 000 points
            (``t[-1] / dt``: 600 s at 1 ms).
    """
    owner = "invert_cooperation"
    alpha = float(alpha)
    if not (math.isfinite(alpha) and 0.0 < alpha < 1.0):
        raise ConfigError(f"{owner}: alpha must lie in (0, 1), got {alpha!r}")
    f_max = _check_positive("f_max", f_max, owner)
    dt = _check_positive("dt", dt, owner)
    t = np.asarray(t, dtype=np.float64)
    c = np.asarray(cooperation, dtype=np.float64)
    if t.ndim != 1 or t.shape != c.shape or t.size < 2:
        raise ConfigError(
            f"{owner}: t and cooperation must be 1-D of equal length >= 2, got {t.shape}, {c.shape}"
        )
    if not (np.all(np.isfinite(t)) and np.all(np.isfinite(c))):
        raise ConfigError(f"{owner}: t and cooperation must be finite")
    if t[0] < 0.0 or np.any(np.diff(t) <= 0.0):
        raise ConfigError(f"{owner}: t must be >= 0 and strictly increasing")
    if not t[-1] / dt <= _MAX_GRID:  # before allocating the grid
        raise ConfigError(
            f"{owner}: t[-1] / dt = {t[-1] / dt:.3g} grid points, more than {_MAX_GRID:.3g} "
            f"(t[-1] <= {MAX_SESSION_S:g} s at dt >= {_MAX_GRID_DT:g} s)"
        )
    smoothing = _check_positive("smoothing", smoothing, owner)
    floor = float(floor)
    if not (math.isfinite(floor) and floor >= 0.0):
        raise ConfigError(f"{owner}: floor must be finite and >= 0, got {floor!r}")
    rate = math.log(1.0 / alpha)
    r = 1.0 - c
    grid = np.arange(math.floor(t[-1] / dt + 1e-9) + 1, dtype=np.float64) * dt
    inside = grid >= t[0]
    tg = grid[inside]
    if t.size >= _MIN_SPLINE_POINTS:
        from scipy.interpolate import make_smoothing_spline  # here: a slow import

        lam = smoothing**4 / float(np.mean(np.diff(t)))

        spline = make_smoothing_spline(t, r, lam=lam)
        r_s = spline(tg)
        dr = spline.derivative()(tg)
    else:
        r_s = np.interp(tg, t, r)
        dr = np.interp(tg, t[:-1], np.diff(r) / np.diff(t))
    u = np.empty_like(grid)
    u[inside] = r_s + dr / rate
    if t[0] > 0.0:
        # Constant force from rest: r(t0) = u (1 - alpha^t0).
        u[~inside] = r[0] / (1.0 - alpha ** t[0])
    np.clip(u, 0.0, 1.0, out=u)
    force = u * f_max
    force[force < floor] = 0.0
    return grid, force


class ReplayUser:
    """A user who replays a recorded session's resistance.

    At construction the recorded cooperation is inverted (:func:`invert_cooperation`) into the
    post-deadband force ``|F~|(t)`` on a ``dt`` grid; the person then pushes against the motion
    with ``|F| = |F~| + deadband`` where ``|F~| > 0``, so that the measured (deadbanded) force fed
    to the cooperation filter at ``1/dt`` reproduces the recorded ``c(t)``. Between grid points the
    force is interpolated linearly; after the recording ends the user cooperates fully (0 N). The
    replay is deterministic: :meth:`reset` draws nothing.

    Args:
        session: The recorded session (at least ``t`` and ``cooperation``).
        alpha: Cooperation filter decay factor (per second), in (0, 1).
        f_max: Cooperation filter force scale (N), > 0.
        deadband: Force sensor deadband (N), >= 0.
        dt: Control period (s) of the grid the force is tabulated on, > 0.
        smoothing: Smoothing time scale (s) of the inversion (:func:`invert_cooperation`).
        floor: Smallest post-deadband force (N) replayed (:func:`invert_cooperation`).

    Raises:
        ConfigError: on a bad argument (names it).
    """

    def __init__(
        self,
        session: Session,
        *,
        alpha: float = DEFAULT_ALPHA,
        f_max: float = DEFAULT_F_MAX,
        deadband: float = DEFAULT_DEADBAND,
        dt: float = 0.002,
        smoothing: float = 0.05,
        floor: float = 0.05,
    ) -> None:
        if not isinstance(session, Session):
            raise ConfigError(
                f"ReplayUser: session must be a Session, got {type(session).__name__}"
            )
        deadband = float(deadband)
        if not (math.isfinite(deadband) and deadband >= 0.0):
            raise ConfigError(f"ReplayUser: deadband must be finite and >= 0, got {deadband!r}")
        self.session = session
        self.alpha = float(alpha)
        self.f_max = float(f_max)
        self.deadband = deadband
        self.dt = float(dt)
        grid, f_tilde = invert_cooperation(
            session.t,
            session.cooperation,
            alpha=alpha,
            f_max=f_max,
            dt=dt,
            smoothing=smoothing,
            floor=floor,
        )
        grid.setflags(write=False)
        f_tilde.setflags(write=False)
        self.grid = grid
        """Tabulation times (m,), s."""
        self.f_tilde = f_tilde
        """Post-deadband force magnitude (m,), N, at :attr:`grid`."""
        f_raw = np.where(f_tilde > 0.0, f_tilde + deadband, 0.0)
        f_raw.setflags(write=False)
        self.f_applied = f_raw
        """Force magnitude the person applies (m,), N, at :attr:`grid`."""
        self._table = f_raw.tolist()

    @classmethod
    def from_csv(cls, path: str | Path, **kwargs: float) -> ReplayUser:
        """Load a session CSV (:func:`load_session`) and replay it (``kwargs``: as ``__init__``)."""
        return cls(load_session(path), **kwargs)

    @property
    def end_time(self) -> float:
        """Time (s) after which the user no longer resists."""
        return float(self.grid[-1])

    def reset(self, rng: np.random.Generator) -> None:
        """Nothing to draw: a replay is deterministic."""

    def magnitude(self, t: float) -> float:
        """Force magnitude (N) the person applies at time ``t`` (s); 0 after the recording."""
        return sample_table(self._table, self.dt, t)

    def magnitude_array(self, t: np.ndarray) -> np.ndarray:
        """Vectorised :meth:`magnitude`: ``t`` (...,), s, to magnitudes of the same shape, N."""
        return sample_table_array(self.f_applied, self.dt, t)

    def force_table(self) -> tuple[np.ndarray, float]:
        """The tabulated magnitudes (m,), N, and their step (s): :meth:`force` is
        ``against_motion(sample_table(table, step, t), tangent)`` (the env's compiled ticks)."""
        return self.f_applied, self.dt

    def force(self, t: float, hand_velocity: np.ndarray, tangent: np.ndarray) -> np.ndarray:
        """Force (3,), N: :meth:`magnitude` along ``-tangent``."""
        return against_motion(self.magnitude(t), tangent)

    def __repr__(self) -> str:
        return f"ReplayUser({self.session.name!r}, {self.end_time:.2f} s)"
