"""Reading and validating recorded-session CSVs (SPEC §3).

A session file is a comma-separated table with a header row. Only ``t`` (s since the session
started, strictly increasing) and ``cooperation`` (in [0, 1]) are required, so any lab's
recordings with at least these two columns load. The other SPEC §3 columns (``ee_speed``,
``audio_pace``, ``physical_pace``, ``t_a``, ``t_x``, ``em``) are read when present; any further
columns are ignored. Column names are matched after stripping whitespace and lower-casing. Times
must lie in ``[0, MAX_SESSION_S]`` (600 s) with samples at least ``MIN_SAMPLE_SPACING`` (0.1 ms)
apart (:mod:`langenv.validation`), so that what a replay allocates is bounded by these limits,
not by whatever a file says.
"""

from __future__ import annotations

import csv
import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from langenv.errors import SessionDataError
from langenv.validation import MAX_SESSION_S, MIN_SAMPLE_SPACING, check_time_axis

__all__ = [
    "MAX_SESSION_S",
    "MIN_SAMPLE_SPACING",
    "OPTIONAL_COLUMNS",
    "REQUIRED_COLUMNS",
    "Session",
    "load_session",
    "load_sessions",
    "write_session",
]

REQUIRED_COLUMNS: tuple[str, ...] = ("t", "cooperation")
"""Columns every session file must have."""

OPTIONAL_COLUMNS: tuple[str, ...] = (
    "ee_speed",
    "audio_pace",
    "physical_pace",
    "t_a",
    "t_x",
    "em",
)
"""SPEC §3 columns read when present (``None`` in :class:`Session` otherwise)."""


@dataclass(frozen=True, eq=False)
class Session:
    """One recorded session: time series sampled at the instants ``t``.

    All arrays have shape ``(n,)`` (``n >= 2``), float64, and are read-only.

    Attributes:
        name: The file's stem (``"u3_lc"`` for ``u3_lc.csv``).
        t: Time since the session started (s), strictly increasing, in ``[0, MAX_SESSION_S]``,
            samples at least ``MIN_SAMPLE_SPACING`` apart.
        cooperation: The controller's cooperation estimate ``c(t)`` in [0, 1].
        ee_speed: Hand speed (m/s), or ``None`` if the file has no such column.
        audio_pace: Audio pace ``a(t)``, or ``None``.
        physical_pace: Physical pace ``p(t)``, or ``None``.
        t_a: Estimated time to complete the speech (s), or ``None``.
        t_x: Estimated time to complete the motion (s), or ``None``.
        em: Estimated misalignment ``t_a - t_x`` (s), or ``None``.
        path: The file it was read from, or ``None`` when built in memory.
    """

    name: str
    t: np.ndarray
    cooperation: np.ndarray
    ee_speed: np.ndarray | None = None
    audio_pace: np.ndarray | None = None
    physical_pace: np.ndarray | None = None
    t_a: np.ndarray | None = None
    t_x: np.ndarray | None = None
    em: np.ndarray | None = None
    path: Path | None = None

    def __post_init__(self) -> None:
        where = str(self.path) if self.path is not None else f"session {self.name!r}"
        at = _line if self.path is not None else _index
        t = _frozen_column(self.t, "t", where, at)
        n = t.shape[0]
        if n < 2:
            raise SessionDataError(f"{where}: needs at least 2 rows, got {n}")
        bad = np.flatnonzero(np.diff(t) <= 0.0)
        if bad.size:
            i = int(bad[0])
            raise SessionDataError(
                f"{where}: column 't' must be strictly increasing, but {at(i + 1)} "
                f"has t={t[i + 1]!r} after t={t[i]!r}"
            )
        check_time_axis(t, where, SessionDataError, at)
        c = _frozen_column(self.cooperation, "cooperation", where, at, n)
        out = np.flatnonzero((c < 0.0) | (c > 1.0))
        if out.size:
            i = int(out[0])
            raise SessionDataError(
                f"{where}: column 'cooperation' must lie in [0, 1], but {at(i)} has {c[i]!r}"
            )
        object.__setattr__(self, "t", t)
        object.__setattr__(self, "cooperation", c)
        for name in OPTIONAL_COLUMNS:
            value = getattr(self, name)
            if value is not None:
                object.__setattr__(self, name, _frozen_column(value, name, where, at, n))

    @property
    def duration(self) -> float:
        """Time span ``t[-1] - t[0]`` of the recording (s)."""
        return float(self.t[-1] - self.t[0])

    @property
    def columns(self) -> tuple[str, ...]:
        """Names of the columns present (required first, then the optional ones found)."""
        return REQUIRED_COLUMNS + tuple(c for c in OPTIONAL_COLUMNS if getattr(self, c) is not None)


def _line(i: int) -> str:
    """Where data row ``i`` (0-based) sits in a file whose header is line 1."""
    return f"line {i + 2}"


def _index(i: int) -> str:
    return f"index {i}"


def _frozen_column(
    value: object, name: str, where: str, at: Callable[[int], str], n: int | None = None
) -> np.ndarray:
    arr = np.array(value, dtype=np.float64, copy=True)
    if arr.ndim != 1:
        raise SessionDataError(f"{where}: column {name!r} must be 1-D, got shape {arr.shape}")
    if n is not None and arr.shape[0] != n:
        raise SessionDataError(f"{where}: column {name!r} has {arr.shape[0]} values, expected {n}")
    bad = np.flatnonzero(~np.isfinite(arr))
    if bad.size:
        i = int(bad[0])
        raise SessionDataError(
            f"{where}: column {name!r} must be finite, but {at(i)} has {arr[i]!r}"
        )
    arr.setflags(write=False)
    return arr


def load_session(path: str | Path) -> Session:
    """Read and validate one session CSV.

    Args:
        path: The CSV file (comma-separated, header row first).

    Returns:
        The :class:`Session`, named after the file's stem.

    Raises:
        SessionDataError: naming the file (and the column and line where it applies) when the
            file cannot be read or is empty, lacks ``t`` or ``cooperation``, has a row with the
            wrong number of cells, a non-numeric, NaN or infinite cell in a column it reads,
            ``t`` not strictly increasing, starting before 0, ending after
            :data:`MAX_SESSION_S` or with samples closer than :data:`MIN_SAMPLE_SPACING`,
            ``cooperation`` outside [0, 1], or fewer than 2 rows.
    """
    path = Path(path)
    try:
        with path.open(newline="", encoding="utf-8-sig") as fh:
            reader = csv.reader(fh)
            rows = [(reader.line_num, row) for row in reader if any(c.strip() for c in row)]
    except (OSError, UnicodeDecodeError, csv.Error) as exc:
        raise SessionDataError(f"{path}: cannot read session file ({exc})") from exc
    if not rows:
        raise SessionDataError(f"{path}: empty file (expected a header with 't,cooperation')")
    header = [cell.strip().lower() for cell in rows[0][1]]
    index: dict[str, int] = {}
    for j, name in enumerate(header):
        if name in index and name in REQUIRED_COLUMNS + OPTIONAL_COLUMNS:
            raise SessionDataError(f"{path}: column {name!r} appears more than once in the header")
        index.setdefault(name, j)
    missing = [c for c in REQUIRED_COLUMNS if c not in index]
    if missing:
        raise SessionDataError(
            f"{path}: missing required column(s) {', '.join(map(repr, missing))} "
            f"(header has {', '.join(map(repr, header))})"
        )
    data = rows[1:]
    wanted = [c for c in REQUIRED_COLUMNS + OPTIONAL_COLUMNS if c in index]
    columns = {c: _parse_column(path, c, index[c], data, len(header)) for c in wanted}
    return Session(name=path.stem, path=path, **columns)


def _parse_column(
    path: Path, name: str, j: int, data: Sequence[tuple[int, Sequence[str]]], width: int
) -> np.ndarray:
    values = np.empty(len(data), dtype=np.float64)
    for i, (line, row) in enumerate(data):
        if len(row) != width:
            raise SessionDataError(
                f"{path}: line {line} has {len(row)} cells, the header has {width}"
            )
        cell = row[j].strip()
        try:
            value = float(cell)
        except ValueError:
            raise SessionDataError(
                f"{path}: column {name!r}, line {line}: {cell!r} is not a number"
            ) from None
        if not math.isfinite(value):
            raise SessionDataError(f"{path}: column {name!r}, line {line}: {cell!r} is not finite")
        values[i] = value
    return values


def load_sessions(directory: str | Path, pattern: str = "*.csv") -> list[Session]:
    """Read every session file of a directory.

    Args:
        directory: Folder holding the session CSVs.
        pattern: Glob pattern the file names must match.

    Returns:
        The sessions, sorted by file name.

    Raises:
        SessionDataError: if ``directory`` is not a directory or no file matches ``pattern``, or
            as :func:`load_session` for the first bad file.
    """
    directory = Path(directory)
    if not directory.is_dir():
        raise SessionDataError(f"{directory}: not a directory of session files")
    files = sorted(p for p in directory.glob(pattern) if p.is_file())
    if not files:
        raise SessionDataError(f"{directory}: no session files match {pattern!r}")
    return [load_session(p) for p in files]


def write_session(path: str | Path, columns: Mapping[str, Sequence[Any]]) -> Path:
    """Write a session CSV that :func:`load_session` (and ``langctrl compare --sessions``) reads.

    Args:
        path: The file to write (through a temporary file beside it, then renamed).
        columns: Name -> values, all of one length, in the order to write; must include
            :data:`REQUIRED_COLUMNS`. Floats are written with 6 significant digits.

    Returns:
        ``path``.

    Raises:
        SessionDataError: a required column missing or columns of different lengths.
    """
    path = Path(path)
    missing = [c for c in REQUIRED_COLUMNS if c not in columns]
    if missing:
        raise SessionDataError(f"{path}: missing required column(s) {missing}")
    lengths = {len(v) for v in columns.values()}
    if len(lengths) != 1:
        raise SessionDataError(f"{path}: columns of different lengths {sorted(lengths)}")
    tmp = path.with_name(path.name + ".part")
    with tmp.open("w", newline="", encoding="utf-8") as fh:
        writer = csv.writer(fh)
        writer.writerow(list(columns))
        for row in zip(*columns.values(), strict=True):
            writer.writerow([f"{v:.6g}" if isinstance(v, float) else v for v in row])
    tmp.replace(path)
    return path
