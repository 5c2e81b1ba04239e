"""The Language Controller's audio-motion aligner (SPEC §1).

The aligner chooses the physical pace ``p`` and the audio pace ``a`` closest to the natural pace 1
under which motion and speech end together:

    minimise (p - 1)^2 + (a - 1)^2  subject to  t_x / p = t_a / a  (a = p / s, s = t_x / t_a)

whose solution is ``p* = (s^2 + s) / (s^2 + 1)``, ``a* = (s + 1) / (s^2 + 1)``. The paper prints the
two formulas swapped (a typo; the study's lab code has them as here).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from langenv.errors import ConfigError

__all__ = ["AlignerGains", "audio_command", "optimal_paces"]


def optimal_paces(t_x: float, t_a: float) -> tuple[float, float]:
    """Optimal paces ``(p*, a*)`` for motion and speech ETCs at base pace.

    Args:
        t_x: Motion time to completion at p = 1 (s), >= 0.
        t_a: Speech time to completion at a = 1 (s), >= 0.

    Returns:
        ``(p*, a*)`` with ``t_x / p* == t_a / a*`` and ``(p*-1)^2 + (a*-1)^2`` minimal. When speech
        is over (``t_a == 0``) the audio pace no longer matters and ``(1, 1)`` is returned; when
        motion is over (``t_x == 0``) but speech is not, speech should end as fast as allowed,
        which the formula gives as ``p* = 0, a* = 1``.

    Raises:
        ConfigError: if an ETC is negative or not finite.
    """
    if not (math.isfinite(t_x) and t_x >= 0.0):
        raise ConfigError(f"t_x must be finite and >= 0, got {t_x!r}")
    if not (math.isfinite(t_a) and t_a >= 0.0):
        raise ConfigError(f"t_a must be finite and >= 0, got {t_a!r}")
    if t_a == 0.0:
        return 1.0, 1.0
    s = t_x / t_a
    den = s * s + 1.0
    return (s * s + s) / den, (s + 1.0) / den


@dataclass(frozen=True)
class AlignerGains:
    """Gains of the pace laws (SPEC §2 defaults).

    Attributes:
        k_p: Physical pace gain (1/s) in ``dp/dt = k_p (p* - p)``.
        k_a: Audio pace gain (1/s) in ``da/dt = k_a (a* - a) - k_c (1 - c)``.
        k_c: Cooperation gain (1/s).
    """

    k_p: float = 6.0
    k_a: float = 7.0
    k_c: float = 10.0

    def __post_init__(self) -> None:
        for name in ("k_p", "k_a"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0.0):
                raise ConfigError(f"AlignerGains.{name} must be finite and > 0, got {value!r}")
        if not (math.isfinite(self.k_c) and self.k_c >= 0.0):
            raise ConfigError(f"AlignerGains.k_c must be finite and >= 0, got {self.k_c!r}")


def audio_command(a_star: float, cooperation: float, gains: AlignerGains) -> float:
    """Audio pace command that makes ``da/dt = k_a (cmd - a)`` equal the paper's law.

    ``k_a (a* - a) - k_c (1 - c) = k_a ((a* - (k_c / k_a)(1 - c)) - a)``, so the command is
    ``a* - (k_c / k_a)(1 - c)``.

    Args:
        a_star: Optimal audio pace from :func:`optimal_paces`.
        cooperation: Cooperation ``c`` in [0, 1].
        gains: The pace-law gains.

    Returns:
        The audio pace command (may lie below the pace bounds; the plant clips ``a`` itself).
    """
    return a_star - (gains.k_c / gains.k_a) * (1.0 - cooperation)
