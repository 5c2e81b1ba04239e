"""User cooperation ``c`` (SPEC §1, paper eq. "resistance") and its inversion for replay (SPEC §3).

The lab code ran a normalised first-order filter of the deadbanded force magnitude ``|F~|``::

    r <- alpha^dt r + (1 - alpha^dt) min(|F~|, F_max) / F_max,        c = 1 - r,

i.e. ``dr/dt = ln(1/alpha) (min(|F~|, F_max) / F_max - r)``; the step is exact for a force held
over ``dt``. Solving for the force gives the replay law
``|F~|(t) = F_max (r + (dr/dt) / ln(1/alpha))`` (:func:`force_for_cooperation`).
"""

from __future__ import annotations

import math

import numpy as np

from langenv.errors import ConfigError
from langenv.layout import field_table

__all__ = [
    "COOPERATION_SETTINGS",
    "COOPERATION_STATE",
    "CooperationFilter",
    "force_for_cooperation",
]

COOPERATION_STATE = field_table(
    """
    r  the filtered resistance in [0, 1]
    c  cooperation 1 - r
    """
)
"""The filter's state (:attr:`CooperationFilter.r`, :attr:`CooperationFilter.c`)."""
COOPERATION_SETTINGS = field_table(
    """
    keep       alpha^dt: the share of r kept per sample
    inv_f_max  1 / F_max (1/N)
    """
)
"""The filter's settings for a sample period (:meth:`CooperationFilter.settings`)."""


def _check_params(alpha: float, f_max: float, where: str) -> tuple[float, float]:
    alpha, f_max = float(alpha), float(f_max)
    if not (math.isfinite(alpha) and 0.0 < alpha < 1.0):
        raise ConfigError(f"{where}: alpha must lie in (0, 1), got {alpha!r}")
    if not (math.isfinite(f_max) and f_max > 0.0):
        raise ConfigError(f"{where}: f_max must be > 0 and finite, got {f_max!r}")
    return alpha, f_max


class CooperationFilter:
    """The normalised cooperation filter.

    Args:
        alpha: Decay factor per second, in (0, 1) (SPEC §2: 0.1, i.e. a time constant of
            ``1 / ln(1/alpha)`` = 0.43 s).
        f_max: Force (N) at which cooperation reaches 0, > 0 (SPEC §2: 15 N).

    Attributes:
        r: Filtered resistance in [0, 1].
        c: Cooperation ``1 - r`` in [0, 1].

    Raises:
        ConfigError: ``alpha`` outside (0, 1) or ``f_max <= 0`` (names the argument).
    """

    def __init__(self, alpha: float = 0.1, f_max: float = 15.0) -> None:
        self.alpha, self.f_max = _check_params(alpha, f_max, "CooperationFilter")
        self._log_alpha = math.log(self.alpha)
        self._inv_f_max = 1.0 / self.f_max
        self._dt = -1.0
        self._keep = 1.0
        self.r = 0.0
        self.c = 1.0

    @property
    def rate(self) -> float:
        """``ln(1/alpha)`` (1/s), the filter's bandwidth."""
        return -self._log_alpha

    def settings(self, dt: float) -> dict[str, float]:
        """The settings by the names of :data:`COOPERATION_SETTINGS` for samples ``dt`` apart
        (the same ``keep`` as :meth:`update` computes)."""
        keep = self._keep if dt == self._dt else math.exp(self._log_alpha * dt)
        return {"keep": keep, "inv_f_max": self._inv_f_max}

    def reset(self, r: float = 0.0) -> None:
        """Restart from resistance ``r`` (default 0: full cooperation)."""
        r = float(r)
        if not (0.0 <= r <= 1.0):
            raise ConfigError(f"CooperationFilter.reset: r must lie in [0, 1], got {r!r}")
        self.r = r
        self.c = 1.0 - r

    def update(self, f_mag: float, dt: float) -> float:
        """Filter one sample.

        Args:
            f_mag: Measured (deadbanded) force magnitude ``|F~|`` (N), >= 0.
            dt: Time since the previous sample (s), > 0.

        Returns:
            Cooperation ``c`` after the update.

        Raises:
            ConfigError: a negative or non-finite ``f_mag`` or a non-positive ``dt``.
        """
        if not f_mag >= 0.0 or f_mag == math.inf:
            raise ConfigError(
                f"CooperationFilter.update: f_mag must be >= 0 and finite, got {f_mag!r}"
            )
        if dt != self._dt:
            if not (dt > 0.0 and math.isfinite(dt)):
                raise ConfigError(f"CooperationFilter.update: dt must be > 0, got {dt!r}")
            self._dt = dt
            self._keep = math.exp(self._log_alpha * dt)
        u = f_mag * self._inv_f_max
        if u > 1.0:
            u = 1.0
        keep = self._keep
        self.r = keep * self.r + (1.0 - keep) * u
        self.c = 1.0 - self.r
        return self.c

    def run(self, f_mag: np.ndarray, dt: float) -> np.ndarray:
        """Filter a sequence from the current state (convenience for tests and replays).

        Args:
            f_mag: Force magnitudes, shape (n,), N.
            dt: Sample period (s).

        Returns:
            Cooperation after each sample, shape (n,).
        """
        return np.array([self.update(float(f), dt) for f in np.asarray(f_mag, dtype=float)])


def force_for_cooperation(
    t: np.ndarray,
    c: np.ndarray,
    alpha: float = 0.1,
    f_max: float = 15.0,
    smooth: float | None = 0.1,
) -> np.ndarray:
    """The force magnitude that makes :class:`CooperationFilter` output a given ``c(t)``.

    ``|F~|(t) = F_max (r + (dr/dt) / ln(1/alpha))`` with ``r = 1 - c``, clipped to
    ``[0, F_max]`` (a cooperation that rises faster than the filter can, or a force beyond
    ``F_max``, cannot be reproduced exactly).

    Args:
        t: Sample times (s), shape (n,), strictly increasing, n >= 3.
        c: Cooperation samples in [0, 1], shape (n,).
        alpha: Filter decay factor per second, in (0, 1).
        f_max: Filter force scale (N), > 0.
        smooth: Width (s) of the Savitzky-Golay smoothing (quadratic) applied to ``r`` before
            differentiating (digitised traces are noisy); ``None`` or 0 for none.

    Returns:
        Force magnitude ``|F~|`` at each sample time, shape (n,), N.

    Raises:
        ConfigError: mismatched shapes, too few samples, non-increasing or non-finite ``t``,
            non-finite ``c``, or a bad ``alpha``, ``f_max`` or ``smooth`` (names the argument).
    """
    alpha, f_max = _check_params(alpha, f_max, "force_for_cooperation")
    t = np.asarray(t, dtype=np.float64)
    c = np.asarray(c, dtype=np.float64)
    if t.ndim != 1 or t.shape != c.shape:
        raise ConfigError(
            f"force_for_cooperation: t and c must be 1-D of equal length, got {t.shape} and "
            f"{c.shape}"
        )
    if t.size < 3:
        raise ConfigError(f"force_for_cooperation: need at least 3 samples, got {t.size}")
    if not np.all(np.isfinite(t)) or np.any(np.diff(t) <= 0.0):
        raise ConfigError("force_for_cooperation: t must be finite and strictly increasing")
    if not np.all(np.isfinite(c)):
        raise ConfigError("force_for_cooperation: c must be finite")
    r = 1.0 - c
    if smooth is not None and smooth != 0.0:
        if not (math.isfinite(smooth) and smooth > 0.0):
            raise ConfigError(f"force_for_cooperation: smooth must be >= 0, got {smooth!r}")
        step = float(np.median(np.diff(t)))
        window = round(smooth / step) | 1  # odd
        if window >= 5:
            window = min(window, t.size if t.size % 2 else t.size - 1)
            from scipy.signal import savgol_filter  # here: importing scipy.signal takes ~1 s

            r = savgol_filter(r, window, 2, mode="interp")
    dr = np.gradient(r, t)
    force = f_max * (r + dr / -math.log(alpha))
    return np.clip(force, 0.0, f_max)
