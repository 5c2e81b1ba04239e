"""The pace actuator: first-order laws that move ``p`` and ``a`` towards commanded values.

The env applies ``dp/dt = k_p (p_cmd - p)`` and ``da/dt = k_a (a_cmd - a)`` at every 2 ms tick and
clips both paces to their bounds (SPEC §1). With ``p_cmd = p*`` and ``a_cmd = a* - (k_c/k_a)(1-c)``
this is exactly the paper's aligner, so the analytic Language Controller and a learned policy meet
the plant the same way: through pace *commands*.

Agents send normalised commands ``u`` in [-1, 1]; :func:`command_from_action` maps them
piecewise-linearly to pace commands: ``u = 0`` is the natural pace 1, ``u = 1`` the upper bound 1.4,
and ``u = -1`` the lowest command the paper's law can ask for (-1.5: ``a* >= 0`` and the cooperation
term subtracts at most ``k_c / k_a = 10/7``). Commands below the lower pace bound only make the pace
approach that bound faster.

The paper's aligner lives here too, the law the commands come from (SPEC §1): it chooses the
physical pace ``p`` and the audio pace ``a`` closest to the natural pace 1 under which motion and
speech end together,

    minimise (p - 1)^2 + (a - 1)^2  subject to  t_x / p = t_a / a  (a = p / s, s = t_x / t_a)

whose solution is ``p* = (s^2 + s) / (s^2 + 1)``, ``a* = (s + 1) / (s^2 + 1)``
(:func:`optimal_paces`; the paper prints the two formulas swapped, a typo: the study's lab code
has them as here), with the audio command ``a* - (k_c / k_a)(1 - c)`` (:func:`audio_command`).
Its compiled twin is :mod:`langenv.control.pacing_kernels` (the env runs the law there in
``run_law``; ``policies`` imports both from here).
"""

from __future__ import annotations

import math
import numbers
from dataclasses import asdict, dataclass

from langenv.errors import ConfigError
from langenv.layout import field_table

__all__ = [
    "COMMAND_MIN",
    "PACE_LAW",
    "PACE_SETTINGS",
    "PACE_STATE",
    "AlignerGains",
    "PaceActuator",
    "PaceLaw",
    "PaceLimits",
    "action_from_command",
    "aligner_commands",
    "audio_command",
    "command_from_action",
    "misalignment_feedback",
    "optimal_paces",
]

#: Pace command at u = -1 (lowest value the paper's law can ask for).
COMMAND_MIN = -1.5

PACE_STATE = field_table(
    """
    p      physical pace
    a      audio pace
    p_dot  the physical pace's rate in the last tick (1/s)
    """
)
"""The pace actuator's state (:class:`PaceActuator`), declared for the compiled ticks."""
PACE_SETTINGS = field_table(
    """
    k_p    physical pace gain (1/s)
    k_a    audio pace gain (1/s)
    p_min  lower bound of p
    p_max  upper bound of p
    a_min  lower bound of a
    a_max  upper bound of a
    """
)
"""The pace laws' settings (a :class:`PaceLimits`, :meth:`PaceLimits.settings`)."""
PACE_LAW = field_table(
    """
    k_ca       k_c / k_a of the audio command
    k_em       the misalignment feedback on p (1/s)
    em_clip    its bound (pace units)
    law_p_max  the policy's upper bound of p (its action map)
    law_a_max  the policy's upper bound of a
    c_min      the pace command at u = -1 (:data:`COMMAND_MIN`)
    """
)
"""A :class:`PaceLaw` as its compiled form reads it (:meth:`PaceLaw.values`)."""


@dataclass(frozen=True)
class PaceLimits:
    """Bounds and gains of the pace laws.

    Attributes:
        p_min: Lower bound of the physical pace (> 0).
        p_max: Upper bound of the physical pace.
        a_min: Lower bound of the audio pace (> 0).
        a_max: Upper bound of the audio pace.
        k_p: Physical pace gain (1/s).
        k_a: Audio pace gain (1/s).
    """

    p_min: float = 0.6
    p_max: float = 1.4
    a_min: float = 0.6
    a_max: float = 1.4
    k_p: float = 6.0
    k_a: float = 7.0

    def settings(self) -> dict[str, float]:
        """The bounds and gains by the names of :data:`PACE_SETTINGS`."""
        return asdict(self)

    def __post_init__(self) -> None:
        for name in ("p_min", "p_max", "a_min", "a_max", "k_p", "k_a"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0.0):
                raise ConfigError(f"PaceLimits.{name} must be finite and > 0, got {value!r}")
        if not self.p_min < 1.0 < self.p_max:
            raise ConfigError(
                f"PaceLimits needs p_min < 1 < p_max, got [{self.p_min}, {self.p_max}]"
            )
        if not self.a_min < 1.0 < self.a_max:
            raise ConfigError(
                f"PaceLimits needs a_min < 1 < a_max, got [{self.a_min}, {self.a_max}]"
            )


@dataclass(frozen=True)
class PaceLaw:
    """The paper's aligner as a law the env can apply itself at every tick
    (:meth:`LangCtrlEnv.run_law <langenv.env.LangCtrlEnv.run_law>`).

    What a policy deciding at 500 Hz does with the observation, exactly: ``p* , a*`` the optimal
    paces of the observed ``t_x``, ``t_a`` (negative readings as 0), ``p_cmd = p* - clip(k_em
    (t_a - t_x), +-em_clip)`` while the motion goes on (``k_em = 0``: the paper's ``p* ``),
    ``a_cmd = a* - (k_c / k_a)(1 - c)``, sent as the action :func:`action_from_command` gives
    under ``limits`` with a next-phrase value of 0 (the paper's phrase rule). ``policies``' LC
    and LC-noAP are this law (their ``pace_law()``).

    Attributes:
        k_c: Cooperation gain (1/s), >= 0.
        k_a: Audio pace gain (1/s), > 0 (the env's own ``PaceLimits.k_a`` for the paper's law).
        k_em: Feedback of the misalignment ``t_a - t_x`` on the physical pace command (1/s), >= 0.
        em_clip: Bound of that feedback (pace units), >= 0.
        limits: The pace limits the policy maps its commands to actions with.
    """

    k_c: float
    k_a: float
    k_em: float = 0.0
    em_clip: float = 0.5
    limits: PaceLimits = PaceLimits()

    def __post_init__(self) -> None:
        for name in ("k_c", "k_a", "k_em", "em_clip"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, numbers.Real):
                raise ConfigError(f"PaceLaw.{name} must be a number, got {value!r}")
            value = float(value)
            object.__setattr__(self, name, value)  # a NumPy scalar kept as a float
            if not (math.isfinite(value) and value >= 0.0):
                raise ConfigError(f"PaceLaw.{name} must be finite and >= 0, got {value!r}")
        if not self.k_a > 0.0:
            raise ConfigError(f"PaceLaw.k_a must be > 0, got {self.k_a!r}")
        if not isinstance(self.limits, PaceLimits):
            raise ConfigError(f"PaceLaw.limits must be PaceLimits, got {self.limits!r}")

    def values(self) -> dict[str, float]:
        """The law by the names of :data:`PACE_LAW`."""
        return {
            "k_ca": self.k_c / self.k_a, "k_em": self.k_em, "em_clip": self.em_clip,
            "law_p_max": self.limits.p_max, "law_a_max": self.limits.a_max,
            "c_min": COMMAND_MIN,
        }  # fmt: skip


def command_from_action(u: float, upper: float) -> float:
    """Map a normalised action ``u`` in [-1, 1] to a pace command.

    Args:
        u: Normalised command.
        upper: Pace upper bound (the command at ``u = 1``).

    Returns:
        ``1 + (upper - 1) u`` for ``u >= 0``, ``1 + (1 - COMMAND_MIN) u`` for ``u < 0``.
    """
    if u >= 0.0:
        return 1.0 + (upper - 1.0) * u
    return 1.0 + (1.0 - COMMAND_MIN) * u


def action_from_command(cmd: float, upper: float) -> float:
    """Inverse of :func:`command_from_action`, clipped to [-1, 1]."""
    if cmd >= 1.0:
        u = (cmd - 1.0) / (upper - 1.0)
    else:
        u = (cmd - 1.0) / (1.0 - COMMAND_MIN)
    return min(1.0, max(-1.0, u))


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


def misalignment_feedback(t_x: float, t_a: float, k_em: float, em_clip: float) -> float:
    """What the misalignment feedback takes off ``p*`` (``lc-em``, not in the paper):
    ``clip(k_em (t_a - t_x), +-em_clip)``."""
    return min(em_clip, max(-em_clip, k_em * (t_a - t_x)))


def aligner_commands(
    t_x: float,
    t_a: float,
    cooperation: float,
    gains: AlignerGains,
    k_em: float = 0.0,
    em_clip: float = 0.5,
    motion_on: bool = True,
) -> tuple[float, float]:
    """The aligner's pace commands ``(p_cmd, a_cmd)`` for ETCs ``t_x, t_a >= 0`` and the
    cooperation: ``p*`` less :func:`misalignment_feedback` while the motion goes on (``k_em >
    0``), and :func:`audio_command` of ``a*`` (:class:`PaceLaw`'s law)."""
    p_star, a_star = optimal_paces(t_x, t_a)
    a_cmd = audio_command(a_star, cooperation, gains)
    if k_em > 0.0 and motion_on:
        p_star -= misalignment_feedback(t_x, t_a, k_em, em_clip)
    return p_star, a_cmd


class PaceActuator:
    """State ``(p, a)`` moved by the first-order pace laws at each tick.

    Args:
        limits: Bounds and gains.
    """

    def __init__(self, limits: PaceLimits) -> None:
        self.limits = limits
        self.p = 1.0
        self.a = 1.0
        self.p_dot = 0.0

    def reset(self) -> None:
        """Both paces back to the natural pace 1."""
        self.p = 1.0
        self.a = 1.0
        self.p_dot = 0.0

    def step(self, p_cmd: float, a_cmd: float, dt: float) -> None:
        """Advance the paces one tick (explicit Euler, as the lab code's 500 Hz loop).

        Args:
            p_cmd: Physical pace command.
            a_cmd: Audio pace command.
            dt: Tick length (s).
        """
        lim = self.limits
        p_new = self.p + dt * lim.k_p * (p_cmd - self.p)
        p_new = min(lim.p_max, max(lim.p_min, p_new))
        self.p_dot = (p_new - self.p) / dt
        self.p = p_new
        a_new = self.a + dt * lim.k_a * (a_cmd - self.a)
        self.a = min(lim.a_max, max(lim.a_min, a_new))
