"""The reward compiled (:mod:`langenv.task.reward`): the same operations in the same order,
``x ** 2`` through the C library's ``pow`` as CPython computes it
(:func:`langenv.kernels.mjc.py_square`)."""

from __future__ import annotations

from langenv.kernels import inline
from langenv.kernels.mjc import py_square

__all__ = ["integrands", "step_terms", "total"]


@inline
def integrands(
    pow_fn: int, t_a: float, a: float, t_x: float, p: float, motion_on: bool, speech_on: bool
) -> tuple[float, float]:
    """:func:`langenv.task.reward.integrands` (``pow_fn``: the C library's ``pow``)."""
    em = abs(t_a / a - t_x / p) if (motion_on or speech_on) else 0.0
    pace = (py_square(pow_fn, p - 1.0) if motion_on else 0.0) + (
        py_square(pow_fn, a - 1.0) if speech_on else 0.0
    )
    return em, pace


@inline
def step_terms(
    em_int: float, pace_int: float, w_em: float, w_pace: float, t_scale: float
) -> tuple[float, float]:
    """:func:`langenv.task.reward.step_terms` (``t_scale``:
    :data:`~langenv.task.observation.T_SCALE`)."""
    return -w_em * em_int / t_scale, -w_pace * pace_int


@inline
def total(r_em: float, r_pace: float, r_am: float) -> float:
    """:func:`langenv.task.reward.total`."""
    return r_em + r_pace + r_am
