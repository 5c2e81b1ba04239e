"""FastETC's tables on disk: built once per machine instead of once per process.

:class:`~langenv.control.motion_etc.FastETC` tabulates the motion law of a trajectory and its
admittance parameters (about 3 s of CPU for the UR5 exercise). Every process that makes the env
built them again: each ``eval.compare`` worker, each training subprocess, each test process. This
module keeps them in ``$LANGCTRL_ETC_CACHE`` (default ``~/.cache/langctrl/etc``; ``off`` turns the
disk cache off) as ``<digest>.npz``. The digest hashes the tables' key (geometry, admittance and
guide parameters, the legs' lengths, switch distances and turn angles, table settings), the
package version *and the source of the code that builds them* (every module of
``langenv.control`` and ``langenv.kernels``, and :mod:`langenv.layout`), so an edit of that code,
or another version of the package, never reads stale tables. A file that cannot be read or does
not match is ignored (and replaced); a directory that cannot be written, or sources that cannot
be read (a zipped install), leave the tables in memory only (one warning per process). Files are
never pruned: each code version and parameter set adds one of 1-3 MB; delete the directory to
reclaim the space.
"""

from __future__ import annotations

import hashlib
import os
import warnings
import zipfile
from pathlib import Path

import numpy as np

from langenv.files import temp_file

__all__ = ["etc_cache_dir", "load_tables", "store_tables", "tables_digest"]

_FORMAT = 1  # bump when the stored arrays' meaning changes
_SOURCE_DIRS = ("control", "kernels")  # the packages whose code builds the tables
_SOURCE_FILES = ("layout.py",)  # and the declarations their arrays are packed by
_code_digest: str | None = None
_warned = False


def etc_cache_dir() -> Path | None:
    """Directory of the cache: ``$LANGCTRL_ETC_CACHE`` or ``~/.cache/langctrl/etc``; ``None`` when
    ``LANGCTRL_ETC_CACHE`` is ``off``."""
    env = os.environ.get("LANGCTRL_ETC_CACHE")
    if env is not None and env.strip().lower() == "off":
        return None
    if env:
        return Path(env).expanduser()
    return Path.home() / ".cache" / "langctrl" / "etc"


def _code() -> str:
    """SHA-256 of the package version and the source files that build the tables (read once per
    process).

    Raises:
        OSError: if a source file cannot be read.
    """
    global _code_digest
    if _code_digest is None:
        import langenv

        root = Path(__file__).resolve().parent.parent
        h = hashlib.sha256(langenv.__version__.encode())
        files = sorted(f for d in _SOURCE_DIRS for f in (root / d).glob("*.py"))
        if not files:
            raise OSError(f"no source files under {root}")
        files += [root / name for name in _SOURCE_FILES]
        for f in files:
            h.update(f.relative_to(root).as_posix().encode())
            h.update(f.read_bytes())
        _code_digest = h.hexdigest()
    return _code_digest


def tables_digest(key: tuple[object, ...]) -> str:
    """File stem of the tables of ``key`` (FastETC's in-memory key: floats' ``repr`` is exact)."""
    h = hashlib.sha256(f"{_FORMAT}|{_code()}|{key!r}".encode())
    return h.hexdigest()[:32]


def load_tables(key: tuple[object, ...]) -> tuple[np.ndarray, np.ndarray] | None:
    """The stored ``(prm, tab)`` of ``key`` (read-only float64 vectors), or ``None``."""
    root = etc_cache_dir()
    if root is None:
        return None
    try:
        path = root / f"{tables_digest(key)}.npz"
        with np.load(path, allow_pickle=False) as data:
            prm, tab = data["prm"], data["tab"]
    except (OSError, ValueError, KeyError, EOFError, zipfile.BadZipFile):  # absent or damaged
        return None
    for arr in (prm, tab):
        if arr.ndim != 1 or arr.dtype != np.float64 or arr.size == 0:
            return None
        arr.setflags(write=False)
    return prm, tab


def store_tables(key: tuple[object, ...], prm: np.ndarray, tab: np.ndarray) -> None:
    """Write ``(prm, tab)`` of ``key`` atomically (no partial file is ever read)."""
    global _warned
    root = etc_cache_dir()
    if root is None:
        return
    try:
        name = f"{tables_digest(key)}.npz"
        root.mkdir(parents=True, exist_ok=True)
        fd, tmp = temp_file(root, suffix=".npz.part")
        try:
            with os.fdopen(fd, "wb") as f:
                np.savez(f, prm=prm, tab=tab)
            os.replace(tmp, root / name)
        except BaseException:
            tmp.unlink(missing_ok=True)
            raise
    except OSError as exc:
        if not _warned:
            _warned = True
            warnings.warn(
                f"FastETC table cache {root} cannot be used ({exc}); tables are kept in memory "
                "only (set LANGCTRL_ETC_CACHE to a writable directory, or to 'off')",
                RuntimeWarning,
                stacklevel=2,
            )
