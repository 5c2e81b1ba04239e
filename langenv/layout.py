"""Declared state: each part names its numbers once; slots, packing and batches derive from it.

A part of the tick (the guide, the admittance, the cooperation filter, the pace laws, the speech
timeline, the safety monitor, ...) keeps its state and settings in its Python object, the
reference. Its compiled twin works on plain float64 arrays. What joins the two is a *declaration*:
the part lists its fields (name, size, type, meaning) once, in the module of its reference, as a
tuple of :class:`Field`. A :class:`Layout` places the fields of one or more parts one after
another in a flat float64 array, and everything else is derived from it, as MuJoCo derives
``mjData``'s layout from ``mjxmacro.h``:

* the slot of every field (:attr:`Layout.at`, a named tuple: ``ws[TICK.at.r]``); Numba reads a
  module-level named tuple as constants, so a kernel that indexes by it costs what a hand-written
  number did;
* packing and unpacking by name (:meth:`Layout.pack`, :meth:`Layout.unpack`), checked against the
  declaration (an unknown or missing name, a wrong size);
* a batch of ``n`` sessions: ``layout.zeros(n)``, one row per session, each row the array one
  session's kernels take (:mod:`langenv.batch`);
* the documentation (:meth:`Layout.table`).

A part writes its declaration as a table, one field a line (:func:`field_table`), the way
``mjxmacro.h`` lists ``mjData``'s arrays::

    PACE_STATE = field_table('''
        p      physical pace
        a      audio pace
        p_dot  the physical pace's rate in the last tick (1/s)
    ''')

Every value is stored as float64; a field's ``kind`` says how :meth:`Layout.unpack` gives it back
(``"float"``, ``"int"``, ``"bool"``; ``"index"`` is an int where -1 means none). Changing a
declaration changes the slots of every kernel that reads it: the kernels' disk cache is dropped
(:func:`langenv.kernels.clear_stale_cache` watches every module that declares or compiles).
"""

from __future__ import annotations

import re
import textwrap
from collections import namedtuple
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from langenv.errors import ConfigError

__all__ = ["Field", "Layout", "field_table", "table_rows"]

_KINDS = ("float", "int", "bool", "index")
_HEAD = re.compile(r"(?P<name>[A-Za-z_]\w*)(?:\[(?P<size>\d+)\])?(?::(?P<kind>\w+))?$")


@dataclass(frozen=True)
class Field:
    """One named entry (or a run of ``size`` entries) of a part's state or settings.

    Attributes:
        name: A Python identifier, unique within a layout.
        size: Number of float64 entries (1: a scalar; 3: a vector in the base frame).
        kind: How the value reads back: ``"float"``, ``"int"``, ``"bool"`` or ``"index"`` (an
            int, -1 for none).
        doc: Meaning and unit.
    """

    name: str
    size: int = 1
    kind: str = "float"
    doc: str = ""

    def __post_init__(self) -> None:
        if not self.name.isidentifier() or self.name.startswith("_"):
            raise ConfigError(f"Field.name must be a public identifier, got {self.name!r}")
        if isinstance(self.size, bool) or not isinstance(self.size, int) or self.size < 1:
            raise ConfigError(f"Field {self.name!r}: size must be an int >= 1, got {self.size!r}")
        if self.kind not in _KINDS:
            raise ConfigError(
                f"Field {self.name!r}: kind must be one of {_KINDS}, got {self.kind!r}"
            )


class Layout:
    """Fields placed one after another in a flat float64 array.

    Args:
        name: The layout's name (in messages and the documentation).
        parts: Tuples of :class:`Field` (a part's declaration) or other layouts, in order.

    Raises:
        ConfigError: if two fields share a name.
    """

    def __init__(self, name: str, *parts: Iterable[Field] | Layout) -> None:
        fields: list[Field] = []
        for part in parts:
            fields.extend(part.fields if isinstance(part, Layout) else part)
        offsets: dict[str, int] = {}
        at = 0
        for f in fields:
            if f.name in offsets:
                raise ConfigError(f"layout {name!r}: field {f.name!r} is declared twice")
            offsets[f.name] = at
            at += f.size
        self.name = name
        self.fields: tuple[Field, ...] = tuple(fields)
        self.size: int = at
        """Number of float64 entries."""
        self._offsets = offsets
        self._by_name = {f.name: f for f in fields}
        slots = namedtuple(f"{_camel(name)}Slots", list(offsets))  # type: ignore[misc]
        self.at: Any = slots(**offsets)
        """The slot of each field by name (a named tuple of ints; Numba reads it as constants)."""

    def __contains__(self, name: object) -> bool:
        return name in self._offsets

    def __repr__(self) -> str:
        return f"Layout({self.name!r}, {len(self.fields)} fields, size {self.size})"

    def slot(self, name: str) -> int:
        """The first entry of field ``name``."""
        try:
            return self._offsets[name]
        except KeyError:
            raise ConfigError(
                f"layout {self.name!r} has no field {name!r}; fields: {', '.join(self._offsets)}"
            ) from None

    def span(self, first: str, last: str) -> slice:
        """The entries from field ``first`` to field ``last``, both included (for one bulk read
        or write of adjacent fields)."""
        a, b = self.slot(first), self.slot(last)
        if b < a:
            raise ConfigError(f"layout {self.name!r}: {last!r} comes before {first!r}")
        return slice(a, b + self._by_name[last].size)

    def names(self, first: str, last: str) -> tuple[str, ...]:
        """Names of the fields from ``first`` to ``last`` (both included), in order."""
        s = self.span(first, last)
        return tuple(f.name for f in self.fields if s.start <= self._offsets[f.name] < s.stop)

    def zeros(self, n: int | None = None, extra: int = 0) -> np.ndarray:
        """A zeroed array: shape ``(size + extra,)``, or ``(n, size + extra)`` (one row per
        session of a batch)."""
        width = self.size + extra
        return np.zeros(width if n is None else (n, width))

    def pack(self, out: np.ndarray, values: Mapping[str, Any]) -> np.ndarray:
        """Write ``values`` (name -> a number, or ``size`` numbers) into ``out``; returns it.

        Raises:
            ConfigError: for a name the layout does not declare or a value of the wrong size.
        """
        for name, value in values.items():
            f = self._by_name.get(name)
            if f is None:
                raise ConfigError(
                    f"layout {self.name!r} has no field {name!r}; fields: "
                    f"{', '.join(self._offsets)}"
                )
            at = self._offsets[name]
            if f.size == 1:
                out[at] = -1.0 if (f.kind == "index" and value is None) else float(value)
            else:
                arr = np.asarray(value, dtype=np.float64).reshape(-1)
                if arr.size != f.size:
                    raise ConfigError(
                        f"layout {self.name!r}: field {name!r} takes {f.size} values, "
                        f"got {arr.size}"
                    )
                out[at : at + f.size] = arr
        return out

    def pack_all(self, out: np.ndarray, *groups: Mapping[str, Any]) -> np.ndarray:
        """:meth:`pack` of ``groups`` together, which must name every field exactly once."""
        merged: dict[str, Any] = {}
        for g in groups:
            twice = sorted(set(g) & set(merged))
            if twice:
                raise ConfigError(f"layout {self.name!r}: {', '.join(twice)} given twice")
            merged.update(g)
        missing = [f.name for f in self.fields if f.name not in merged]
        if missing:
            raise ConfigError(f"layout {self.name!r}: no value for {', '.join(missing)}")
        return self.pack(out, merged)

    def unpack(self, arr: np.ndarray, names: Sequence[str] | None = None) -> dict[str, Any]:
        """The fields ``names`` (default: all) of ``arr`` as Python values by their kind (a
        float, an int, a bool, an int or None for an index; a vector as a new array)."""
        out: dict[str, Any] = {}
        for name in names if names is not None else self._offsets:
            f = self._by_name[name]
            at = self._offsets[name]
            if f.size > 1:
                out[name] = np.array(arr[at : at + f.size], dtype=np.float64)
                continue
            v = float(arr[at])
            if f.kind == "int":
                out[name] = int(v)
            elif f.kind == "bool":
                out[name] = v != 0.0
            elif f.kind == "index":
                out[name] = None if v < 0.0 else int(v)
            else:
                out[name] = v
        return out

    def table(self) -> str:
        """The layout as a Markdown table: slot, name, size, kind, meaning."""
        rows = ["| slot | field | size | kind | meaning |", "|---|---|---|---|---|"]
        for f in self.fields:
            rows.append(
                f"| {self._offsets[f.name]} | ``{f.name}`` | {f.size} | {f.kind} | {f.doc} |"
            )
        return "\n".join(rows)


def field_table(table: str) -> tuple[Field, ...]:
    """The fields of a declaration written as a table, one field a line: ``NAME  MEANING``,
    where ``NAME`` may carry a size and a kind (``end_tangent[3]``, ``n_legs:int``,
    ``leg[2]:index``; default 1 and ``"float"``) and a line indented deeper than the names
    continues the meaning above it. Blank lines are skipped.

    Raises:
        ConfigError: naming the line, for a malformed name or a continuation before any field
            (and :class:`Field`'s own checks: a size below 1, an unknown kind).
    """
    fields = []
    for m, doc in table_rows(table, _HEAD, "NAME[SIZE]:KIND"):
        fields.append(Field(m["name"], int(m["size"] or 1), m["kind"] or "float", doc))
    return tuple(fields)


def table_rows(table: str, head: re.Pattern[str], form: str) -> list[tuple[re.Match[str], str]]:
    """The rows of a declaration's table (:func:`field_table`): each line's first word matched
    by ``head`` and the rest of the line, with the deeper-indented lines below it.

    Raises:
        ConfigError: naming the line, for a first word ``head`` does not match (``form`` says
            what it should be) or a continuation before any row.
    """
    rows: list[tuple[re.Match[str], list[str]]] = []
    for k, line in enumerate(textwrap.dedent(table).splitlines(), 1):
        if not line.strip():
            continue
        if line[0].isspace():
            if not rows:
                raise ConfigError(f"fields table line {k}: a continuation before any field")
            rows[-1][1].append(line.strip())
            continue
        word, _, doc = line.partition(" ")
        m = head.match(word)
        if m is None:
            raise ConfigError(f"fields table line {k}: {word!r} is not {form}")
        rows.append((m, [doc.strip()]))
    return [(m, " ".join(parts)) for m, parts in rows]


def _camel(name: str) -> str:
    return "".join(part.capitalize() for part in name.replace("-", "_").split("_")) or "Layout"
