"""Outputs that appear whole or not at all: a file via a temporary name and a rename, a directory
made beside its destination and moved into place.

Used by :mod:`eval.report` and :mod:`eval.plots` (tables and figures), :mod:`eval.compare` (its
whole output directory) and :mod:`eval.sweep` (Parquet part files, written durably so that a
machine that reboots mid-sweep leaves either a whole part or none). Files and folders get the
user's normal mode (:mod:`langenv.files`, where :func:`atomic_write` lives).
"""

from __future__ import annotations

import os
import shutil
from pathlib import Path

from langenv.files import atomic_write, temp_dir

__all__ = ["OutTaken", "atomic_write", "make_tmp_dir", "move_into_place"]


class OutTaken(Exception):
    """The destination is no longer ours to write: the outputs stay in the temporary directory."""


def make_tmp_dir(out: Path) -> Path:
    """A new temporary directory beside ``out`` (same file system, so it can be renamed to it).

    Raises:
        OSError: ``out``'s parent cannot be made or written.
    """
    out.parent.mkdir(parents=True, exist_ok=True)
    return temp_dir(out.parent, prefix=f".{out.name}.tmp-")


def move_into_place(tmp: Path, out: Path, overwrite: bool) -> None:
    """Move the finished outputs from ``tmp`` to ``out``.

    A missing or empty ``out`` is replaced by ``tmp`` whole (one rename). Otherwise, with
    ``overwrite``, each output replaces the entry of the same name, which is moved aside first and
    deleted only once the new one is in place; every other entry stays.

    Raises:
        OutTaken: ``out`` was filled by someone else during the run (without ``overwrite``).
    """
    if not out.exists():
        tmp.rename(out)
        return
    if not any(out.iterdir()):
        out.rmdir()
        tmp.rename(out)
        return
    if not overwrite:
        raise OutTaken(f"--out {out}: files appeared in it during the run")
    for entry in sorted(tmp.iterdir()):
        target = out / entry.name
        old = None
        if target.exists() or target.is_symlink():
            old = out / f".{entry.name}.old-{os.getpid()}"
            target.rename(old)
        entry.rename(target)
        if old is not None:
            if old.is_dir() and not old.is_symlink():
                shutil.rmtree(old)
            else:
                old.unlink()
