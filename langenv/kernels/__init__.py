"""The compiled-code toolkit of the 500 Hz hot path (numba, ``nopython`` mode, cached on disk).

Each law's compiled twin sits beside its Python reference (``control/guide_kernels.py`` beside
``control/guide.py``, ``robot/arm_kernels.py`` beside ``robot/arm.py``, ...) and works on arrays
whose layout the part declares once (:mod:`langenv.layout`); :mod:`langenv.motion.tick_kernels`
composes them into one tick and :mod:`langenv.env_kernels` into the env's ticks. This package
holds what they share: the decorators (:func:`jit`, :func:`kernel`, :func:`inline`),
:mod:`~langenv.kernels.blas` (MuJoCo's dense routines, in MuJoCo's order),
:mod:`~langenv.kernels.pymath` (CPython's ``hypot``/``dist``) and :mod:`~langenv.kernels.mjc`
(MuJoCo's steps and the C library's ``pow``, called by address). It imports nothing of langenv
but its errors and the layouts.

The kernels repeat their references' arithmetic operation for operation (the same order of
additions, MuJoCo's own order for its BLAS routines, no ``fastmath``), so a compiled episode is
bit-identical to the Python one.

Numba checks a cached kernel against its own source file only, while these kernels call each
other across files and read the slots of declarations made in other files: importing the
package drops the cached kernels of every module in :data:`COMPILED` whenever any file of
:data:`SOURCES` changed (:func:`clear_stale_cache`), so an edit to ``guide.py``'s declaration
cannot leave ``env_kernels.run`` running with the old slots.
"""

from __future__ import annotations

import hashlib
import os
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any, TypeVar, cast

import numba

from langenv.files import temp_file

__all__ = ["COMPILED", "SOURCES", "clear_stale_cache", "inline", "jit", "kernel"]

COMPILED = (
    "kernels/blas.py",
    "kernels/mjc.py",
    "kernels/pymath.py",
    "kernels/views.py",
    "control/trajectory_kernels.py",
    "control/motion_etc_kernels.py",
    "control/guide_kernels.py",
    "control/admittance_kernels.py",
    "control/cooperation_kernels.py",
    "control/command_kernels.py",
    "robot/arm_kernels.py",
    "robot/force_sensor_kernels.py",
    "users/noise_kernels.py",
    "users/table_kernels.py",
    "speech/legs_kernels.py",
    "speech/choice_kernels.py",
    "speech/graph_kernels.py",
    "robot/safety_kernels.py",
    "control/pacing_kernels.py",
    "task/reward_kernels.py",
    "task/observation_kernels.py",
    "motion/tick_kernels.py",
    "env_kernels.py",
    "batch/kernels.py",
)
"""The modules (relative to ``langenv/``) whose compiled kernels call each other or read other
files' declarations: their disk caches are dropped together. (``speech/vocoder_kernels.py`` is
self-contained: numba's own check of its file suffices.)"""
SOURCES = (
    *COMPILED,
    "kernels/__init__.py",
    "layout.py",
    "task/observation.py",
    "control/trajectory.py",
    "control/guide.py",
    "control/admittance.py",
    "control/cooperation.py",
    "control/command.py",
    "robot/arm.py",
    "robot/force_sensor.py",
    "robot/safety.py",
    "control/pacing.py",
    "speech/timeline.py",
    "speech/legs.py",
)
"""The files whose content the compiled kernels depend on: :data:`COMPILED` and the parts'
declarations (``tests/test_architecture.py`` checks that every module importing
:mod:`langenv.layout` or this package is listed)."""

_STAMP = "langctrl-kernels.sha256"


def _cache_dirs(directory: Path) -> list[Path]:
    """Where numba keeps the caches of the modules in ``directory``: its ``__pycache__``, and
    under ``NUMBA_CACHE_DIR`` where that is set (numba's ``UserProvidedCacheLocator``)."""
    dirs = [directory / "__pycache__"]
    base = getattr(numba.config, "CACHE_DIR", "")
    if base:
        full = os.path.abspath(directory)
        dirs.append(
            Path(base)
            / "_".join([os.path.split(full)[-1], hashlib.sha1(full.encode()).hexdigest()])
        )
    return dirs


def clear_stale_cache(
    root: Path, sources: Sequence[str], compiled: Sequence[str], stamp: str = "kernels"
) -> bool:
    """Delete numba's cache files of the modules ``compiled`` (paths relative to ``root``) unless
    the files ``sources`` (relative to ``root``, or absolute) are those they were compiled from
    (a digest kept in the cache of ``root/stamp``); returns whether any was deleted. Other
    packages whose kernels read langenv's declarations call it too
    (:mod:`policies.residual_kernels`).

    Fails quietly where the cache cannot be written (a read-only install: its sources do not
    change, and numba then caches elsewhere, per file).
    """
    stamp_dir = root / stamp / "__pycache__"
    stamp_file = stamp_dir / _STAMP
    try:
        digest = hashlib.sha256()
        for name in sorted(sources):
            path = root / name
            data = path.read_bytes() if path.is_file() else b"(none)"
            digest.update(name.encode() + b"\0" + data)
        if stamp_file.is_file() and stamp_file.read_text() == digest.hexdigest():
            return False
        stale: list[Path] = []
        for name in compiled:
            module = root / name
            for cache in _cache_dirs(module.parent):
                stale.extend(sorted(cache.glob(f"{module.stem}.*.nb[ic]")))
        for path in stale:
            path.unlink(missing_ok=True)
        stamp_dir.mkdir(parents=True, exist_ok=True)
        fd, tmp = temp_file(stamp_dir, prefix=f".{_STAMP}.")
        with os.fdopen(fd, "w") as fh:
            fh.write(digest.hexdigest())
        os.replace(tmp, stamp_file)
        return bool(stale)
    except OSError:
        return False


clear_stale_cache(Path(__file__).resolve().parent.parent, SOURCES, COMPILED)

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
