"""The comparison's verdict on the terminal: a table per policy, the study's findings, the files.

``langctrl compare`` ends with it. On a terminal it is drawn with rich (a table, coloured
PASS/FAIL); when the output is a file or a pipe it is plain text (aligned columns, no colour, no
box characters), so logs stay readable.

The table has one row per policy: the median over users of ``|AM|``, the mean over users of the
mean ``|EM|`` and of the mean ``|a - 1|`` while speaking, the mean shares of speech time at
``|a - 1| <= 0.1``, in pauses and in fillers, the share of the motion in which words are
heard (``content %``) and of the legs whose words start within 1 s of the leg (``legs in step
%``; when the rows have them), the number of truncated
episodes when
there are any, the number of protective stops when ``sessions.csv`` has a column for them
(the first of :data:`STOP_COLUMNS` present) and the phrase graph each policy spoke when it has a
``graph`` column; policies of one graph role that spoke different graphs are marked
(:data:`~eval.report.MIXED_MARK`) and a line under the table says what that means.
"""

from __future__ import annotations

import math
import sys
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import IO, Any

import numpy as np

from eval.report import (
    MIXED_MARK,
    display_name,
    graphs_spoken,
    mixed_graph_policies,
    study_findings,
)

__all__ = ["SHARES_NOTE", "STOP_COLUMNS", "print_verdict"]

STOP_COLUMNS: tuple[str, ...] = (
    "protective_stops",
    "safety_stops",
    "protective_stop",
    "safety_stop",
)
"""Columns of ``sessions.csv`` counted as protective stops per episode, in order of preference."""

Row = Mapping[str, Any]


_SHARE_COLUMNS = {
    "a_within_0_1": "|a-1|<=0.1 %",
    "voice_natural": "voice natural %",
    "pause_share": "pauses %",
    "filler_share": "fillers %",
    "content_share": "content %",
    "legs_in_step": "legs in step %",
}
"""Shares shown (mean over users, in percent) when the rows have them: of the speech time, for
``content_share`` of the motion's duration (words heard, :mod:`eval.metrics`), for
``legs_in_step`` of the legs whose words start within 1 s of the leg (:mod:`eval.legs`; n/a
for a graph without ``@leg`` marks)."""

SHARES_NOTE = (
    "% columns: the mean over sessions of each session's share of its speech time (content %: "
    "of its motion); summary.md gives their medians, the third finding pools all speech time"
)
"""The line under the table that says which statistic each share is (one name per measure)."""


def _values(rows: Sequence[Row], policy: str, column: str) -> np.ndarray:
    out = []
    for r in rows:
        if r.get("policy") != policy:
            continue
        try:
            out.append(float(r[column]))
        except (KeyError, TypeError, ValueError):
            out.append(math.nan)
    return np.asarray(out, dtype=np.float64)


def _stat(x: np.ndarray, how: str) -> float:
    x = x[np.isfinite(x)]
    if not x.size:
        return math.nan
    return float(np.median(x) if how == "median" else np.mean(x))


def _fmt(x: float, digits: int = 2) -> str:
    return "n/a" if not math.isfinite(x) else f"{x:.{digits}f}"


def verdict_table(
    rows: Sequence[Row], policies: Sequence[str]
) -> tuple[list[str], list[list[str]]]:
    """Header and body of the per-policy table.

    Args:
        rows: Session rows (``policy``, ``abs_am``, ``em_mean_abs``, ``a_dev``, optionally
            ``truncated`` and a protective-stop column of :data:`STOP_COLUMNS`).
        policies: Policies in display order.
    """
    header = ["policy", "users", "median |AM| (s)", "mean |EM| (s)", "mean |a - 1|"]
    columns = set().union(*(r.keys() for r in rows)) if rows else set()
    shares = [c for c in _SHARE_COLUMNS if c in columns]
    header += [_SHARE_COLUMNS[c] for c in shares]
    stop_col = next((c for c in STOP_COLUMNS if c in columns), None)
    truncated = "truncated" in columns and any(
        _values(rows, p, "truncated").sum() > 0 for p in policies
    )
    if truncated:
        header.append("truncated")
    if stop_col is not None:
        header.append("protective stops")
    spoken = graphs_spoken(rows, policies)
    mixed = mixed_graph_policies(rows, policies)
    if spoken:
        header.append("graph")
    body = []
    for p in policies:
        line = [
            display_name(p),
            str(len(_values(rows, p, "abs_am"))),
            _fmt(_stat(_values(rows, p, "abs_am"), "median")),
            _fmt(_stat(_values(rows, p, "em_mean_abs"), "mean")),
            _fmt(_stat(_values(rows, p, "a_dev"), "mean"), 3),
        ]
        line += [_fmt(100.0 * _stat(_values(rows, p, c), "mean"), 1) for c in shares]
        if truncated:
            line.append(str(int(np.nansum(_values(rows, p, "truncated")))))
        if stop_col is not None:
            line.append(str(int(np.nansum(_values(rows, p, stop_col)))))
        if spoken:
            line.append(spoken[p] + (f" {MIXED_MARK}" if p in mixed else ""))
        body.append(line)
    return header, body


def print_verdict(
    rows: Sequence[Row],
    policies: Sequence[str],
    out: Path,
    files: Sequence[tuple[str, str]],
    *,
    file: IO[str] | None = None,
    terminal: bool | None = None,
) -> None:
    """Print the verdict.

    Args:
        rows: Session rows as read back from ``sessions.csv``.
        policies: Policies in display order.
        out: The output directory.
        files: ``(path relative to out, what it holds)`` for each kind of file written.
        file: Where to print (default: standard output).
        terminal: Draw for a terminal (rich table, colour); default: whether ``file`` is one.
    """
    from rich import box
    from rich.console import Console
    from rich.markup import escape
    from rich.table import Table

    stream = file if file is not None else sys.stdout
    if terminal is None:
        terminal = bool(getattr(stream, "isatty", lambda: False)())
    console = Console(
        file=stream,
        force_terminal=terminal,
        no_color=not terminal,
        highlight=False,
        emoji=False,
        width=None if terminal else 300,  # a log's lines are as long as the table needs
    )
    header, body = verdict_table(rows, policies)
    table = Table(
        box=box.SIMPLE_HEAD if terminal else None,
        title=None,
        show_edge=False,
        pad_edge=False,
        header_style="bold" if terminal else "",
    )
    for k, name in enumerate(header):
        if name == "graph":  # a path: left, and folded rather than cut on a narrow terminal
            table.add_column(name, justify="left", overflow="fold")
        else:
            table.add_column(name, justify="left" if k == 0 else "right")
    for cells in body:
        table.add_row(*cells)
    console.print(table)
    if any(name in _SHARE_COLUMNS.values() for name in header):
        console.print(SHARES_NOTE, markup=False)
    mixed = mixed_graph_policies(rows, policies)
    if mixed:
        names = ", ".join(display_name(p) for p in mixed)
        console.print(
            f"{MIXED_MARK} {names} spoke different phrase graphs in one role "
            "(--allow-mixed-graphs): their figures compare scripts as well as controllers",
            markup=False,
        )

    console.print("study's findings:" if not terminal else "[bold]study's findings[/bold]")
    styles = {"PASS": "bold green", "FAIL": "bold red", "n/a": "dim"}
    for f in study_findings(list(rows)):
        verdict = f.verdict
        if terminal:
            line = f"  [{styles[verdict]}]{verdict:<4}[/]  {escape(f.claim)}: {escape(f.measured)}"
        else:
            line = f"  {verdict:<4}  {f.claim}: {f.measured}"
        console.print(line, markup=terminal)
    console.print("files:" if not terminal else "[bold]files[/bold]")
    paths = [str(out / name) + ("/" if name.endswith("/") else "") for name, _ in files]
    width = max((len(p) for p in paths), default=0)
    for path, (_, what) in zip(paths, files, strict=True):
        console.print(f"  {path:<{width}}  {what}", markup=False)
