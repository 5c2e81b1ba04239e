"""ForceSensor: the measured human force, with Gaussian noise and a soft deadband."""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from langenv import vec
from langenv.errors import ActionError, ConfigError
from langenv.layout import field_table

__all__ = ["SENSOR_SETTINGS", "SENSOR_STATE", "ForceSensor"]

SENSOR_STATE = field_table(
    """
    f_measured[3]  the last reading, after the deadband (N)
    """
)
"""The sensor's reading, declared for the compiled tick."""
SENSOR_SETTINGS = field_table(
    """
    deadband  the deadband's radius (N)
    """
)
"""The sensor's settings (the compiled tick draws no noise: a noisy sensor ticks in Python)."""


class ForceSensor:
    """Force/torque sensor at the handle: Gaussian noise, then a soft deadband.

    The deadband is ``F~ = F * max(0, 1 - deadband / |F|)``: zero for ``|F| <= deadband``, and
    above it the magnitude is ``|F| - deadband`` in the direction of ``F`` (continuous in ``F``).

    Args:
        noise_std: standard deviation (N) of the zero-mean Gaussian noise added to each axis.
        deadband: deadband radius (N).

    Raises:
        ConfigError: ``noise_std`` or ``deadband`` negative or not finite.
    """

    def __init__(self, noise_std: float = 0.0, deadband: float = 5.0) -> None:
        for name, value in (("noise_std", noise_std), ("deadband", deadband)):
            try:
                v = float(value)
            except (TypeError, ValueError) as exc:
                raise ConfigError(f"{name} must be a number, got {value!r}") from exc
            if not math.isfinite(v) or v < 0.0:
                raise ConfigError(f"{name} must be finite and >= 0, got {value!r}")
        self.noise_std = float(noise_std)
        self.deadband = float(deadband)

    def measure(
        self, f: NDArray[np.float64], rng: np.random.Generator | None
    ) -> NDArray[np.float64]:
        """Measure a force.

        Args:
            f: (3,) true force on the handle (N, base frame).
            rng: source of the noise; no noise when ``None`` or ``noise_std == 0``.

        Returns:
            (3,) float64 measured force after noise and deadband (N), a new array.

        Raises:
            ActionError: ``f`` is not a finite (3,) vector.
        """
        arr = f if type(f) is np.ndarray and f.dtype == np.float64 else np.asarray(f, np.float64)
        if arr.shape != (3,):
            raise ActionError(f"f must have shape (3,), got shape {arr.shape}")
        if rng is not None and self.noise_std > 0.0:
            arr = arr + rng.normal(0.0, self.noise_std, 3)
        norm2 = vec.sumsq(arr)
        if not norm2 < math.inf:
            raise ActionError(f"f must be finite, got {np.asarray(f).tolist()}")
        norm = math.sqrt(norm2)
        if norm <= self.deadband:
            return np.zeros(3)
        return arr * (1.0 - self.deadband / norm)

    def magnitude(self, f: NDArray[np.float64], rng: np.random.Generator | None) -> float:
        """``|measure(f, rng)|`` (N), the input of the cooperation filter."""
        return vec.norm(self.measure(f, rng))
