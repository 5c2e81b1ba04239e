"""Outputs that appear whole or not at all: a file via a temporary name and a rename, a directory
made beside its destination and moved into place.

Used by :mod:`eval.report` and :mod:`eval.plots` (tables and figures), :mod:`eval.compare` (its
whole output directory) and :mod:`eval.sweep` (Parquet part files, written durably so that a
machine that reboots mid-sweep leaves either a whole part or none).
"""

from __future__ import annotations

import os
import shutil
import tempfile
from pathlib import Path

__all__ = ["OutTaken", "atomic_write", "make_tmp_dir", "move_into_place"]


class OutTaken(Exception):
    """The destination is no longer ours to write: the outputs stay in the temporary directory."""


def atomic_write(path: str | Path, data: str | bytes, *, durable: bool = False) -> Path:
    """Write ``data`` to ``path`` via a temporary file in the same directory and a rename.

    Args:
        path: Destination; its directory must exist.
        data: Text (written as UTF-8) or bytes.
        durable: Also flush the file and its directory to disk (``fsync``), so that after a
            power loss or reboot the file is there whole or not at all (costs a few ms).

    Returns:
        The path written.
    """
    path = Path(path)
    payload = data.encode("utf-8") if isinstance(data, str) else data
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(payload)
            if durable:
                fh.flush()
                os.fsync(fh.fileno())
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    if durable and hasattr(os, "O_DIRECTORY"):
        dir_fd = os.open(path.parent, os.O_DIRECTORY)
        try:
            os.fsync(dir_fd)
        finally:
            os.close(dir_fd)
    return path


def make_tmp_dir(out: Path) -> Path:
    """A new temporary directory beside ``out`` (same file system, so it can be renamed to it).

    Raises:
        OSError: ``out``'s parent cannot be made or written.
    """
    out.parent.mkdir(parents=True, exist_ok=True)
    return Path(tempfile.mkdtemp(prefix=f".{out.name}.tmp-", dir=out.parent))


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
