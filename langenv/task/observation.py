"""The observation of ``LangCtrl-v0``: the one home of its layout and scales.

The env writes its observation through :class:`ObservationEncoder`; policies read it through the
decoders below, by the field names of :class:`Obs`. Every field lies in ``[-1, 1]`` (the encoder
clips):

| index | field | physical value | encoding | decoder |
|---|---|---|---|---|
| 0 | ``T_X`` | motion ETC at base pace ``t_x`` (s) | ``t / 40`` | :func:`seconds` |
| 1 | ``T_A`` | speech ETC at base pace ``t_a`` (s) | ``t / 40`` | :func:`seconds` |
| 2 | ``MISALIGNMENT`` | ``t_a/a - t_x/p`` at current paces (s) | ``t / 40`` | :func:`seconds` |
| 3 | ``P`` | physical pace ``p`` | ``(p - 1) / 0.4`` | :func:`pace` |
| 4 | ``A`` | audio pace ``a`` | ``(a - 1) / 0.4`` | :func:`pace` |
| 5 | ``COOPERATION`` | cooperation ``c`` in [0, 1] | ``2c - 1`` | :func:`fraction` |
| 6 | ``COOPERATION_TREND`` | ``dc/dt`` over the last 0.5 s (1/s) | as is | :func:`value` |
| 7 | ``PROGRESS`` | progress ``d`` along the path in [0, 1] | ``2d - 1`` | :func:`fraction` |
| 8 | ``HAND_SPEED`` | hand speed (m/s) | ``v / 0.25`` | :func:`hand_speed` |
| 9 | ``PHRASE_SAID`` | share of the current phrase said | ``2f - 1`` | :func:`fraction` |
| 10 | ``PHRASE_LEFT`` | rest of the phrase at ``a = 1`` (s) | ``t / 40`` | :func:`seconds` |
| 11 | ``IN_PAUSE`` | in silence: the pause after a clip, or a pause vertex | ±1 | :func:`flag` |
| 12 | ``SPEECH_DONE`` | speech over | ±1 | :func:`flag` |
| 13 | ``MOTION_DONE`` | motion over | ±1 | :func:`flag` |
| 14 | ``BOUNDARY_DUE`` | a phrase boundary is due before the next decision | ±1 | :func:`flag` |
| 15 | ``ELAPSED`` | time since the episode began (s) | ``t / 60`` | :func:`elapsed` |
| 16 + 3k | child ``k``: ``VALID`` | child ``k`` is a valid next phrase | ±1 | :func:`child` |
| 17 + 3k | child ``k``: ``T_MIN`` | its ``t_min`` (s) | ``t / 40`` | :func:`child` |
| 18 + 3k | child ``k``: ``T_MAX`` | its ``t_max`` (s) | ``t / 40`` | :func:`child` |

The scales are normalisations, not bounds: a value beyond them (a pace outside ``[0.6, 1.4]``
under wider :class:`~langenv.control.pacing.PaceLimits`, a time above 40 s) reads as ±1.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from enum import IntEnum

import numpy as np

__all__ = [
    "CHILD_FIELDS",
    "ELAPSED_SCALE",
    "FIRST_CHILD",
    "PACE_SCALE",
    "SPEED_SCALE",
    "TREND_WINDOW",
    "T_SCALE",
    "ChildField",
    "Obs",
    "ObsValues",
    "ObservationEncoder",
    "child",
    "child_index",
    "elapsed",
    "encode_elapsed",
    "encode_flag",
    "encode_fraction",
    "encode_pace",
    "encode_seconds",
    "encode_speed",
    "flag",
    "fraction",
    "hand_speed",
    "observation_size",
    "pace",
    "seconds",
    "value",
]

T_SCALE = 40.0
"""Scale of the times in the observation (s)."""
PACE_SCALE = 0.4
"""Scale of the paces' deviation from 1."""
SPEED_SCALE = 0.25
"""Scale of the hand speed (m/s)."""
ELAPSED_SCALE = 60.0
"""Scale of the elapsed time (s)."""
TREND_WINDOW = 0.5
"""Window of the cooperation trend (s)."""


class Obs(IntEnum):
    """Index of each fixed field of the observation (see the module's table)."""

    T_X = 0
    T_A = 1
    MISALIGNMENT = 2
    P = 3
    A = 4
    COOPERATION = 5
    COOPERATION_TREND = 6
    PROGRESS = 7
    HAND_SPEED = 8
    PHRASE_SAID = 9
    PHRASE_LEFT = 10
    IN_PAUSE = 11
    SPEECH_DONE = 12
    MOTION_DONE = 13
    BOUNDARY_DUE = 14
    ELAPSED = 15


class ChildField(IntEnum):
    """Offset of each field within a child's block of :data:`CHILD_FIELDS` entries."""

    VALID = 0
    T_MIN = 1
    T_MAX = 2


FIRST_CHILD = len(Obs)
"""Index of the first child's block."""
CHILD_FIELDS = len(ChildField)
"""Entries per child."""


def observation_size(max_children: int) -> int:
    """Length of the observation for a phrase graph whose largest out-degree is ``max_children``."""
    return FIRST_CHILD + CHILD_FIELDS * max_children


def child_index(k: int, field: ChildField = ChildField.VALID) -> int:
    """Index of ``field`` of child ``k`` (0-based)."""
    return FIRST_CHILD + CHILD_FIELDS * k + field


# ---------------------------------------------------------------------------------- encoders
def encode_seconds(t: float) -> float:
    """A time (s) as observed: ``t / T_SCALE``."""
    return t / T_SCALE


def encode_pace(p: float) -> float:
    """A pace as observed: ``(p - 1) / PACE_SCALE``."""
    return (p - 1.0) / PACE_SCALE


def encode_fraction(f: float) -> float:
    """A share in [0, 1] as observed: ``2 f - 1``."""
    return 2.0 * f - 1.0


def encode_flag(b: bool) -> float:
    """A yes/no as observed: ``+1`` / ``-1``."""
    return 1.0 if b else -1.0


def encode_speed(v: float) -> float:
    """The hand speed (m/s) as observed: ``v / SPEED_SCALE``."""
    return v / SPEED_SCALE


def encode_elapsed(t: float) -> float:
    """The elapsed time (s) as observed: ``t / ELAPSED_SCALE``."""
    return t / ELAPSED_SCALE


# ---------------------------------------------------------------------------------- decoders
ObsValues = np.ndarray | Sequence[float]
"""What the decoders read: an observation, or its values as a list (``obs.tolist()``, which is
cheaper to read many fields from: a list item is a Python float, an array item a NumPy scalar)."""


def seconds(obs: ObsValues, field: int) -> float:
    """A time field (``T_X``, ``T_A``, ``MISALIGNMENT``, ``PHRASE_LEFT``) in s."""
    return float(obs[field]) * T_SCALE


def pace(obs: ObsValues, field: int) -> float:
    """A pace field (``P``, ``A``)."""
    return 1.0 + PACE_SCALE * float(obs[field])


def fraction(obs: ObsValues, field: int) -> float:
    """A share in [0, 1] (``COOPERATION``, ``PROGRESS``, ``PHRASE_SAID``)."""
    return 0.5 * (float(obs[field]) + 1.0)


def flag(obs: ObsValues, field: int) -> bool:
    """A yes/no field (``IN_PAUSE``, ``SPEECH_DONE``, ``MOTION_DONE``, ``BOUNDARY_DUE``)."""
    return bool(obs[field] > 0.0)


def value(obs: ObsValues, field: int) -> float:
    """A field stored as is (``COOPERATION_TREND``, 1/s)."""
    return float(obs[field])


def hand_speed(obs: ObsValues) -> float:
    """The hand speed (m/s)."""
    return float(obs[Obs.HAND_SPEED]) * SPEED_SCALE


def elapsed(obs: ObsValues) -> float:
    """Time since the episode began (s)."""
    return float(obs[Obs.ELAPSED]) * ELAPSED_SCALE


def child(obs: ObsValues, k: int) -> tuple[bool, float, float] | None:
    """Child ``k`` of the current phrase: ``(valid, t_min, t_max)`` (s), or None past the end of
    the observation."""
    base = child_index(k)
    if base + CHILD_FIELDS > len(obs):
        return None
    valid = bool(obs[base] > 0.0)
    return valid, float(obs[base + 1]) * T_SCALE, float(obs[base + 2]) * T_SCALE


# ---------------------------------------------------------------------------------- the env's side
class ObservationEncoder:
    """Writes observations of a fixed phrase graph (its children's durations encoded once).

    Args:
        max_children: The graph's largest out-degree (at least 1): the number of child blocks.
        durations: ``t_min`` and ``t_max`` (s) of each phrase id that can be a child.
    """

    def __init__(self, max_children: int, durations: Mapping[str, tuple[float, float]]) -> None:
        self.max_children = max_children
        self.size = observation_size(max_children)
        self._blocks = {
            pid: (1.0, _clip(encode_seconds(t_min)), _clip(encode_seconds(t_max)))
            for pid, (t_min, t_max) in durations.items()
        }
        self._empty = (-1.0, 0.0, 0.0)
        self._tails: dict[tuple[str, ...], np.ndarray] = {}

    def _tail(self, children: Sequence[str]) -> np.ndarray:
        """The child blocks of ``children`` (then empty ones), flattened, as float32; cached per
        tuple (read-only)."""
        key = tuple(children)
        tail = self._tails.get(key)
        if tail is None:
            n = len(key)
            blocks = [
                self._blocks[key[k]] if k < n else self._empty for k in range(self.max_children)
            ]
            tail = np.array([v for block in blocks for v in block], np.float32)
            tail.flags.writeable = False
            self._tails[key] = tail
        return tail

    def encode(
        self,
        out: np.ndarray,
        *,
        t_x: float,
        t_a: float,
        p: float,
        a: float,
        cooperation: float,
        cooperation_trend: float,
        progress: float,
        hand_speed: float,
        phrase_said: float,
        phrase_left: float,
        in_pause: bool,
        speech_done: bool,
        motion_done: bool,
        boundary_due: bool,
        elapsed: float,
        children: Sequence[str],
    ) -> np.ndarray:
        """Fill ``out`` (shape ``(size,)``) with the observation, clipped to [-1, 1]; returns it.

        Every entry is clipped in float64 before ``out``'s float32 rounding, which is the same
        as clipping after it (rounding is monotone and +-1 are exact); NaN stays NaN.

        Args:
            children: Ids of the current phrase's children (at most ``max_children``).
        """
        # The encoders' arithmetic written out (the same operations: a call each cost more).
        out[:FIRST_CHILD] = (
            _clip(t_x / T_SCALE),
            _clip(t_a / T_SCALE),
            _clip((t_a / a - t_x / p) / T_SCALE),
            _clip((p - 1.0) / PACE_SCALE),
            _clip((a - 1.0) / PACE_SCALE),
            _clip(2.0 * cooperation - 1.0),
            _clip(cooperation_trend),
            _clip(2.0 * progress - 1.0),
            _clip(hand_speed / SPEED_SCALE),
            _clip(2.0 * phrase_said - 1.0),
            _clip(phrase_left / T_SCALE),
            1.0 if in_pause else -1.0,
            1.0 if speech_done else -1.0,
            1.0 if motion_done else -1.0,
            1.0 if boundary_due else -1.0,
            _clip(elapsed / ELAPSED_SCALE),
        )
        out[FIRST_CHILD:] = self._tail(children)
        return out

    def tail_table(self, order: Sequence[str], children: Mapping[str, Sequence[str]]) -> np.ndarray:
        """The child blocks of each vertex of ``order`` (given its ``children``), one row each,
        then a row for the end of the speech (no children), float32, shape ``(len(order) + 1,
        CHILD_FIELDS * max_children)``: what the compiled encoder copies
        (:func:`langenv.task.observation_kernels.encode`)."""
        rows = [self._tail(children[u]) for u in order]
        rows.append(self._tail(()))
        return np.array(rows, dtype=np.float32).reshape(len(rows), -1)


def _clip(v: float) -> float:
    """``v`` clipped to [-1, 1] (NaN stays NaN, as with ``np.clip``)."""
    return v if -1.0 <= v <= 1.0 else (1.0 if v > 1.0 else (-1.0 if v < -1.0 else v))
