"""The simulated-user protocol, the callable adapter and the helpers shared by all users.

A user is the person holding the robot's handle. Every 2 ms tick the environment asks it for the
force (N, robot base frame) it applies to the handle, given the time since the session started,
the hand's velocity and the exercise path's unit tangent at the hand. Resisting users push against
the motion: along ``-tangent``.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from typing import Protocol, cast, runtime_checkable

import numpy as np

from langenv.errors import ConfigError

__all__ = [
    "DEFAULT_ALPHA",
    "DEFAULT_DEADBAND",
    "DEFAULT_F_MAX",
    "CallableUser",
    "Listener",
    "User",
    "UserForceFn",
    "against_motion",
    "float_view",
    "sample_table",
    "sample_table_array",
]

DEFAULT_ALPHA = 0.1
"""Cooperation filter decay factor alpha (per second), SPEC §2."""
DEFAULT_F_MAX = 15.0
"""Cooperation filter force scale F_max (N), SPEC §2."""
DEFAULT_DEADBAND = 5.0
"""Force sensor deadband (N), SPEC §2."""

UserForceFn = Callable[[float, np.ndarray, np.ndarray], object]
"""``fn(t, hand_velocity, tangent) -> (3,)`` force on the handle (N); see :class:`User`."""


@runtime_checkable
class User(Protocol):
    """A simulated person holding the handle.

    All randomness comes from the generator given to :meth:`reset` (the env's ``np_random``), so
    the same seed gives the same user.
    """

    def reset(self, rng: np.random.Generator) -> None:
        """Start a new session (draw whatever is random about it from ``rng``)."""
        ...

    def force(self, t: float, hand_velocity: np.ndarray, tangent: np.ndarray) -> np.ndarray:
        """Force the person applies to the handle.

        Args:
            t: Time since the session started (s), >= 0.
            hand_velocity: Hand velocity (3,), m/s, robot base frame.
            tangent: Unit tangent (3,) of the exercise path at the hand (direction of progress).

        Returns:
            Force (3,), N, robot base frame.
        """
        ...


@runtime_checkable
class Listener(Protocol):
    """A :class:`User` who listens to the robot: the env tells them what they hear.

    The env calls :meth:`hear` when a wording's last word is heard and, when :attr:`perceives`,
    :meth:`perceive` at every tick; both come before the force of the next tick.
    """

    perceives: bool
    """Whether the person needs the speech's lead (the env computes it only then)."""

    def hear(self, t: float, intent: str | None) -> None:
        """A wording's last word is heard at ``t`` (s); ``intent`` its intent or None."""
        ...

    def perceive(self, t: float, lead: float) -> None:
        """The speech's lead over the motion at ``t``: the speech's progress minus the
        motion's, in seconds of speech (positive: the speech is ahead)."""
        ...


def against_motion(magnitude: float, tangent: np.ndarray) -> np.ndarray:
    """Force of size ``magnitude`` pushing against the direction of progress.

    Args:
        magnitude: Force magnitude (N), >= 0.
        tangent: Path tangent (3,) at the hand; normalised here.

    Returns:
        ``-magnitude * tangent / |tangent|``, shape (3,), N; zeros when ``magnitude == 0``.

    Raises:
        ConfigError: if ``tangent`` is not a finite, non-zero 3-vector while ``magnitude > 0``.
    """
    if magnitude == 0.0:
        return np.zeros(3)
    b = np.asarray(tangent, dtype=np.float64)
    if b.shape != (3,):
        raise ConfigError(f"tangent must have shape (3,), got {b.shape}")
    norm = math.sqrt(float(b[0] * b[0] + b[1] * b[1] + b[2] * b[2]))
    if not (math.isfinite(norm) and norm > 1e-12):
        raise ConfigError(f"tangent must be a finite non-zero vector, got {b.tolist()}")
    return b * (-magnitude / norm)


def float_view(values: np.ndarray) -> Sequence[float]:
    """A read-only 1-D float64 array as a sequence of Python floats, without a copy (a
    ``memoryview``): what :func:`sample_table` reads as fast as a list, for the price of the
    array alone (a list of its floats took four times the array's memory, per session)."""
    if values.ndim != 1 or values.dtype != np.float64 or values.flags.writeable:
        raise ConfigError("float_view: a read-only 1-D float64 array expected")
    return cast("Sequence[float]", np.ascontiguousarray(values).data)  # indexes as floats


def sample_table(table: Sequence[float], step: float, t: float) -> float:
    """Read a force magnitude tabulated every ``step`` seconds from t = 0, at time ``t``.

    Linear between samples, except across a jump from or to 0 (the deadband step between "not
    pushing" and "pushing above the deadband"), where the nearer sample is used; 0 after the last
    sample.

    Args:
        table: Magnitudes (N) at times ``k * step``.
        step: Tabulation step (s), > 0.
        t: Query time (s), >= 0.

    Raises:
        ConfigError: if ``t`` is negative or NaN.
    """
    x = t / step
    if not x >= 0.0:
        raise ConfigError(f"t must be >= 0 s, got {t!r}")
    k = int(x)
    last = len(table) - 1
    if k >= last:
        return table[last] if x == last else 0.0
    f0 = table[k]
    f1 = table[k + 1]
    w = x - k
    if f0 == 0.0 or f1 == 0.0:
        return f0 if w < 0.5 else f1
    return f0 + w * (f1 - f0)


def sample_table_array(table: np.ndarray, step: float, t: np.ndarray) -> np.ndarray:
    """Vectorised :func:`sample_table`: ``table`` (m,), N; ``t`` (...,), s; result shaped as t."""
    x = np.asarray(t, dtype=np.float64) / step
    if np.any(~(x >= 0.0)):
        raise ConfigError("t must be >= 0 s and not NaN")
    last = table.shape[0] - 1
    k = np.minimum(np.floor(x).astype(np.int64), last)
    k1 = np.minimum(k + 1, last)
    w = x - k
    f0 = table[k]
    f1 = table[k1]
    out = np.where((f0 == 0.0) | (f1 == 0.0), np.where(w < 0.5, f0, f1), f0 + w * (f1 - f0))
    return np.where((x > last), 0.0, out)


class CallableUser:
    """Wraps any callable ``fn(t, hand_velocity, tangent) -> (3,)`` as a :class:`User`.

    The callable's output is checked at every call: it must convert to a finite float array of
    shape (3,). A callable that needs randomness can take it from ``on_reset``, which receives the
    env's generator at every :meth:`reset`.

    Args:
        fn: The force law (N), see :meth:`User.force`.
        on_reset: Optional ``on_reset(rng)`` called by :meth:`reset`.
        name: Name used in error messages; defaults to the callable's ``__qualname__``.

    Raises:
        ConfigError: if ``fn`` or ``on_reset`` is not callable.
    """

    def __init__(
        self,
        fn: UserForceFn,
        *,
        on_reset: Callable[[np.random.Generator], None] | None = None,
        name: str | None = None,
    ) -> None:
        if not callable(fn):
            raise ConfigError(f"CallableUser: fn must be callable, got {type(fn).__name__}")
        if on_reset is not None and not callable(on_reset):
            raise ConfigError(
                f"CallableUser: on_reset must be callable or None, got {type(on_reset).__name__}"
            )
        self.fn = fn
        self.on_reset = on_reset
        self.name = name or getattr(fn, "__qualname__", None) or repr(fn)

    def reset(self, rng: np.random.Generator) -> None:
        """Call ``on_reset(rng)`` if one was given."""
        if self.on_reset is not None:
            self.on_reset(rng)

    def force(self, t: float, hand_velocity: np.ndarray, tangent: np.ndarray) -> np.ndarray:
        """Evaluate the callable and validate its output.

        Raises:
            ConfigError: naming the callable, if its output is not a finite (3,) float array.
        """
        out = self.fn(t, hand_velocity, tangent)
        try:
            f = np.asarray(out, dtype=np.float64)
        except (TypeError, ValueError) as exc:
            raise ConfigError(
                f"user callable {self.name!r} must return a (3,) force in N, got {out!r}"
            ) from exc
        if f.shape != (3,):
            raise ConfigError(
                f"user callable {self.name!r} must return a (3,) force in N, got shape {f.shape}"
            )
        if not np.all(np.isfinite(f)):
            raise ConfigError(
                f"user callable {self.name!r} returned a non-finite force {f.tolist()} at t={t}"
            )
        return f

    def __repr__(self) -> str:
        return f"CallableUser({self.name})"
