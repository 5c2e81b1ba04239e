"""Every error of a plain-text script at once, not only the first.

:func:`~langenv.speech.author.parse_script` stops at the first error. :func:`read_script` reads
on past each one: the line in error is read again as a plain one-wording step (a directive as a
blank line), which keeps the steps around it where they were, until the script parses or a line
fails twice; then it raises every error found, one line each (file, line, column), in the order
found. ``langctrl speech author`` reads a script this way before writing its graph, so an author
fixes every error in one pass.
"""

from __future__ import annotations

import re
from pathlib import Path

from langenv.errors import ScriptError
from langenv.speech.author import Script, parse_script

__all__ = ["PLACEHOLDER", "read_script"]

PLACEHOLDER = "Step."
"""What a line in error is read as, to find the errors after it."""


def read_script(source: str, path: str | Path = "<script>") -> Script:
    """The script of ``source`` (:func:`~langenv.speech.author.parse_script`).

    Raises:
        ScriptError: every error found, one line each, naming the file, line and column.
    """
    lines = source.splitlines()
    errors: list[str] = []
    tried: set[int] = set()
    while True:
        try:
            script = parse_script("\n".join(lines), path)
        except ScriptError as exc:
            errors.append(str(exc))
            number = _line_of(str(exc), path)
            if number is None or number in tried or not 1 <= number <= len(lines):
                break
            tried.add(number)
            lines[number - 1] = "" if lines[number - 1].lstrip().startswith("@") else PLACEHOLDER
            continue
        if not errors:
            return script
        break
    raise ScriptError("\n".join(errors))


def _line_of(message: str, path: str | Path) -> int | None:
    """The line an error names (``FILE:LINE:COLUMN: ...``), or None."""
    m = re.match(rf"{re.escape(str(Path(path)))}:(\d+):\d+: ", message)
    return int(m.group(1)) if m else None
