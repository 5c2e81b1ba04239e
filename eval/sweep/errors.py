"""The sweep's own error: a bad sweep file, named by file and key."""

from __future__ import annotations

from collections.abc import Sequence

from langenv.errors import ConfigError

__all__ = ["SweepError"]


class SweepError(ConfigError):
    """A sweep file (or a sweep directory) that cannot be run; nothing has started.

    Attributes:
        file: The sweep file (or directory) at fault.
        key: The key of the first problem (``"grid.lc.k_c (line 7)"``, ``"users[1].synthetic"``),
            ``""`` for the file as a whole.
        detail: What is wrong there and what is allowed.
        problems: Every problem: ``(key, detail)`` pairs, the first one first.
    """

    def __init__(
        self, file: object, key: str, detail: str, more: Sequence[tuple[str, str]] = ()
    ) -> None:
        self.file = str(file)
        self.key = key
        self.detail = detail
        self.problems = ((key, detail), *more)
        lines = [f"{self.file}: {k}: {d}" if k else f"{self.file}: {d}" for k, d in self.problems]
        super().__init__("\n".join(lines))
