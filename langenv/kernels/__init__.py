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

Numba checks a cached kernel against its own source file only, while these kernels call each
other across files: importing the package drops the package's cached kernels whenever any of its
modules changed (:func:`clear_stale_cache`), so an edit to ``tick.py`` cannot leave ``steps.run``
running the old tick.
"""

from __future__ import annotations

import hashlib
import os
import tempfile
from collections.abc import Callable
from pathlib import Path
from typing import Any, TypeVar, cast

import numba

__all__ = ["clear_stale_cache", "inline", "jit", "kernel"]

_STAMP = "langctrl-kernels.sha256"


def clear_stale_cache(sources: Path, cache: Path) -> bool:
    """Delete numba's cache files in ``cache`` unless the ``*.py`` files of ``sources`` are those
    they were compiled from (a digest kept in ``cache``); returns whether any was deleted.

    Fails quietly where ``cache`` cannot be written (a read-only install: its sources do not
    change, and numba then caches elsewhere, per file).
    """
    stamp = cache / _STAMP
    try:
        digest = hashlib.sha256()
        for path in sorted(sources.glob("*.py")):
            digest.update(path.name.encode() + b"\0" + path.read_bytes())
        if stamp.is_file() and stamp.read_text() == digest.hexdigest():
            return False
        stale = sorted(cache.glob("*.nb[ic]"))
        for path in stale:
            path.unlink(missing_ok=True)
        cache.mkdir(exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=f".{_STAMP}.", dir=cache)
        with os.fdopen(fd, "w") as fh:
            fh.write(digest.hexdigest())
        os.replace(tmp, stamp)
        return bool(stale)
    except OSError:
        return False


clear_stale_cache(Path(__file__).parent, Path(__file__).parent / "__pycache__")

F = TypeVar("F", bound=Callable[..., Any])


def _compile(fn: F, **options: Any) -> F:
    """``numba.njit`` with the project's options and ``options`` (``_nrt`` is not in Numba's
    type stubs: the options pass as a mapping)."""
    settings: dict[str, Any] = {"cache": True, "nogil": True, "error_model": "numpy", **options}
    compiled: Any = numba.njit(**settings)(fn)
    return cast(F, compiled)


def jit(fn: F) -> F:
    """Compile ``fn`` in nopython mode, cached on disk (no ``fastmath``: IEEE order kept)."""
    return _compile(fn)


def kernel(fn: F) -> F:
    """:func:`jit` without Numba's reference counting (``_nrt=False``): for the hot path's
    kernels, which allocate no arrays (they write into the arrays they are given). Numba
    otherwise counts the references of every array a function receives or slices, with
    atomic instructions: measured at about 300 per 500 Hz tick, a fifth of the compiled
    controller's time. Such a kernel cannot create or return an array."""
    return _compile(fn, _nrt=False)


def inline(fn: F) -> F:
    """:func:`kernel`, and inlined into every compiled caller (Numba's ``inline="always"``):
    for small helpers called many times per tick, whose call would cost more than their
    arithmetic. A caller that passes constant sizes gets them unrolled. The operations and
    their order are the same as a call's."""
    return _compile(fn, _nrt=False, inline="always")
