"""Compiled kernels of the 500 Hz hot path (numba, ``nopython`` mode, cached on disk).

One control tick of :class:`~langenv.motion.GuidedArm` is one call into compiled code,
:func:`~langenv.kernels.tick.tick`: :func:`~langenv.kernels.tick.control`
(sensor deadband, cooperation filter, guide, admittance, safety limits, speed governor,
acceleration-limited command and the arm's damped-least-squares velocity controller, up to
``ctrl`` and ``qfrc_applied``), MuJoCo's own ``mj_step2``/``mj_step1``/``mj_jacSite``
(:mod:`~langenv.kernels.mjc`) and :func:`~langenv.kernels.tick.observe` (the hand's velocity,
its distance from the path, the motion ETC ``t_x`` and the safety monitor). The Python classes
(:class:`~langenv.control.guide.Guide`, :class:`~langenv.control.motion_etc.FastETC`,
:class:`~langenv.robot.arm.Arm`, ...) stay the reference and the API; the kernels repeat their
arithmetic operation for operation (the same order of additions, MuJoCo's own order for its
BLAS routines), so a compiled episode is bit-identical to the Python one.

Modules: :mod:`~langenv.kernels.blas` (MuJoCo's dense routines), :mod:`~langenv.kernels.path`
(a trajectory as an array: locate, frame, closest point, tool angle),
:mod:`~langenv.kernels.etc` (FastETC's closed form and tables), :mod:`~langenv.kernels.arm`
(the arm's velocity controller), :mod:`~langenv.kernels.tick` (the tick),
:mod:`~langenv.kernels.steps` (the env's ticks of one step: pacing, user, tick, speech, rewards),
:mod:`~langenv.kernels.pacer` (steps of a pace law: what an analytic aligner decides each tick).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, TypeVar, cast

import numba

__all__ = ["jit"]

F = TypeVar("F", bound=Callable[..., Any])


def jit(fn: F) -> F:
    """Compile ``fn`` in nopython mode, cached on disk (no ``fastmath``: IEEE order kept)."""
    compiled: Any = numba.njit(cache=True, nogil=True, error_model="numpy")(fn)
    return cast(F, compiled)
