"""The env's reward: one home for its terms (``LangCtrlEnv``'s "Rewards").

Per tick, while speech or motion goes on, two integrands: the misalignment at current paces
``|t_a/a - t_x/p|`` and the paper's pace objective ``(p-1)^2 [motion on] + (a-1)^2 [speech
on]`` (:func:`integrands`); per step, their integrals weighted (:func:`step_terms`); once, at the
episode's end, ``-w_am |AM|`` (:func:`am_term`). The compiled ticks use the twin,
:mod:`langenv.task.reward_kernels` (the same operations, ``x ** 2`` as CPython computes it).
"""

from __future__ import annotations

from langenv.task.observation import T_SCALE

__all__ = ["am_term", "integrands", "step_terms", "total"]


def integrands(
    t_a: float, a: float, t_x: float, p: float, motion_on: bool, speech_on: bool
) -> tuple[float, float]:
    """``(em, pace)`` after a tick: ``|t_a/a - t_x/p|`` while either goes on (else 0), and
    ``(p-1)^2`` while the motion goes on plus ``(a-1)^2`` while the speech does."""
    em = abs(t_a / a - t_x / p) if (motion_on or speech_on) else 0.0
    pace = ((p - 1.0) ** 2 if motion_on else 0.0) + ((a - 1.0) ** 2 if speech_on else 0.0)
    return em, pace


def step_terms(em_int: float, pace_int: float, w_em: float, w_pace: float) -> tuple[float, float]:
    """A step's ``(reward_em, reward_pace)`` from its integrals (s^2 and s): ``-w_em em_int /
    T_SCALE`` and ``-w_pace pace_int``."""
    return -w_em * em_int / T_SCALE, -w_pace * pace_int


def am_term(am: float, w_am: float) -> float:
    """``reward_am``: ``-w_am |AM|`` (AM in s), paid once when the episode ends (not after a
    protective stop)."""
    return -w_am * abs(am)


def total(r_em: float, r_pace: float, r_am: float) -> float:
    """The step's reward: the terms' sum, in this order."""
    return r_em + r_pace + r_am
