"""Files and folders a job writes, with the user's normal mode.

``tempfile.mkstemp`` makes a file that only its owner may read (``-rw-------``) and
``tempfile.mkdtemp`` such a folder (``drwx------``): right for secrets, wrong for results a lab
shares. A file written under a temporary name and renamed into place, or a folder built aside
and moved in, keeps that mode. The helpers here make them as a plain ``open()`` or ``mkdir()``
would: ``0666`` or ``0777`` less the process's umask (``-rw-r--r--`` and ``drwxr-xr-x`` under
umask 022). Every temporary file or folder that becomes an output or a cache entry is made by
them; :func:`atomic_write` is the one way to write a file whole or not at all.
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

__all__ = ["atomic_write", "temp_dir", "temp_file", "umask"]

_STATUS = Path("/proc/self/status")


def umask() -> int:
    """The process's umask, read without changing it where the system says it (Linux);
    elsewhere set and restored at once."""
    try:
        for line in _STATUS.read_text().splitlines():
            if line.startswith("Umask:"):
                return int(line.split()[1], 8)
    except (OSError, ValueError, IndexError):
        pass
    old = os.umask(0o022)
    os.umask(old)
    return old


def temp_file(directory: str | Path, prefix: str = "", suffix: str = "") -> tuple[int, Path]:
    """``tempfile.mkstemp`` in ``directory`` with a plain ``open()``'s mode; returns the open
    descriptor and the path (the caller renames or removes it)."""
    fd, name = tempfile.mkstemp(prefix=prefix, suffix=suffix, dir=directory)
    try:
        os.chmod(name, 0o666 & ~umask())
    except BaseException:
        os.close(fd)
        Path(name).unlink(missing_ok=True)
        raise
    return fd, Path(name)


def temp_dir(directory: str | Path, prefix: str = "") -> Path:
    """``tempfile.mkdtemp`` in ``directory`` with a plain ``mkdir()``'s mode."""
    path = Path(tempfile.mkdtemp(prefix=prefix, dir=directory))
    try:
        os.chmod(path, 0o777 & ~umask())
    except BaseException:
        path.rmdir()
        raise
    return path


def atomic_write(path: str | Path, data: str | bytes, *, durable: bool = False) -> Path:
    """Write ``data`` to ``path`` via a temporary file in the same directory and a rename.

    Args:
        path: Destination; its directory must exist.
        data: Text (written as UTF-8) or bytes.
        durable: Also flush the file and its directory to disk (``fsync``), so that after a
            power loss or reboot the file is there whole or not at all (costs a few ms).

    Returns:
        The path written (with a plain ``open()``'s mode).
    """
    path = Path(path)
    payload = data.encode("utf-8") if isinstance(data, str) else data
    fd, tmp = temp_file(path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(payload)
            if durable:
                fh.flush()
                os.fsync(fh.fileno())
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    if durable and hasattr(os, "O_DIRECTORY"):
        dir_fd = os.open(path.parent, os.O_DIRECTORY)
        try:
            os.fsync(dir_fd)
        finally:
            os.close(dir_fd)
    return path
