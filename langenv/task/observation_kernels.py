"""The observation's encoder compiled (:meth:`ObservationEncoder.encode
<langenv.task.observation.ObservationEncoder.encode>`): the same values, clipped in float64 and
rounded to float32 as the encoder stores them (``tests/test_batch.py``)."""

from __future__ import annotations

import numpy as np

from langenv.kernels import inline, kernel
from langenv.task.observation import ELAPSED_SCALE, FIRST_CHILD, PACE_SCALE, SPEED_SCALE, T_SCALE

__all__ = ["clip", "encode"]


@inline
def clip(v: float) -> float:
    """``v`` clipped to [-1, 1] (NaN stays NaN): the encoder's ``_clip``."""
    return v if -1.0 <= v <= 1.0 else (1.0 if v > 1.0 else (-1.0 if v < -1.0 else v))


@inline
def _flag(b: bool) -> float:
    return 1.0 if b else -1.0


@kernel
def encode(
    out: np.ndarray,
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
    tail: np.ndarray,
) -> None:
    """Fill ``out`` (float32, the observation's size) as ``ObservationEncoder.encode`` does;
    ``tail``: the child blocks (a row of :meth:`ObservationEncoder.tail_table
    <langenv.task.observation.ObservationEncoder.tail_table>`)."""
    out[0] = np.float32(clip(t_x / T_SCALE))
    out[1] = np.float32(clip(t_a / T_SCALE))
    out[2] = np.float32(clip((t_a / a - t_x / p) / T_SCALE))
    out[3] = np.float32(clip((p - 1.0) / PACE_SCALE))
    out[4] = np.float32(clip((a - 1.0) / PACE_SCALE))
    out[5] = np.float32(clip(2.0 * cooperation - 1.0))
    out[6] = np.float32(clip(cooperation_trend))
    out[7] = np.float32(clip(2.0 * progress - 1.0))
    out[8] = np.float32(clip(hand_speed / SPEED_SCALE))
    out[9] = np.float32(clip(2.0 * phrase_said - 1.0))
    out[10] = np.float32(clip(phrase_left / T_SCALE))
    out[11] = np.float32(_flag(in_pause))
    out[12] = np.float32(_flag(speech_done))
    out[13] = np.float32(_flag(motion_done))
    out[14] = np.float32(_flag(boundary_due))
    out[15] = np.float32(clip(elapsed / ELAPSED_SCALE))
    for j in range(tail.shape[0]):
        out[FIRST_CHILD + j] = tail[j]
