"""Markdown tables, written one way for every report of ``eval`` (``fidelity.md``,
``generalise.md``, ``listening.md``, the exercises' tables).

    >>> print("\\n".join(markdown_table(["policy", "n"], [["lc", "12"]])))
    | policy | n |
    |---|---|
    | lc | 12 |
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence

__all__ = ["markdown_table"]


def markdown_table(header: Sequence[str], rows: Iterable[Sequence[str]]) -> list[str]:
    """The lines of a Markdown table: ``header``, its rule, then one line per row of cells (each
    cell already text; nothing is escaped)."""
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(cells) + " |" for cells in rows]
    return lines
