"""Arrays by address in compiled code: a kernel reaches a session's arrays (kept alive by the
session's own objects) through one row of addresses, its *record*, instead of one argument per
array (:data:`langenv.env_kernels.SESSION`, the single env's and the batch's).

A :class:`Record` declares the arrays once (:class:`ArrayField`: name, dtype, meaning) as a
:class:`~langenv.layout.Layout` of each one's address and length (fields ``<name>`` and
``<name>_n``), and :meth:`Record.pack` writes a row from the arrays by name, checked. In compiled
code :func:`f8`, :func:`i8`, :func:`f8_2` and :func:`f4_2` turn a row's entry back into the array
(``ws = f8(row, RECORD.at.ws)``): a view, no copy, no reference count (a view owns nothing),
emitted inline, so kernels compiled without Numba's reference counting
(:func:`~langenv.kernels.kernel`) may use them. The caller keeps the arrays alive and their
shapes unchanged while the views are used.
"""

from __future__ import annotations

import re
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
from numba import types
from numba.extending import intrinsic
from numba.np.arrayobj import make_array, populate_array

from langenv.errors import ConfigError
from langenv.kernels import inline
from langenv.layout import Field, Layout, table_rows

__all__ = ["ArrayField", "Record", "address", "array_table", "f4_2", "f8", "f8_2", "i8"]

_DTYPES = ("float64", "float32", "int64")


@dataclass(frozen=True)
class ArrayField:
    """One array of a :class:`Record`.

    Attributes:
        name: A public identifier, unique within the record.
        dtype: ``"float64"``, ``"float32"`` or ``"int64"`` (C-contiguous).
        doc: Meaning (and shape, for a 2-D array).
    """

    name: str
    dtype: str = "float64"
    doc: str = ""

    def __post_init__(self) -> None:
        if not self.name.isidentifier() or self.name.startswith("_"):
            raise ConfigError(f"ArrayField.name must be a public identifier, got {self.name!r}")
        if self.dtype not in _DTYPES:
            raise ConfigError(
                f"ArrayField {self.name!r}: dtype must be one of {_DTYPES}, got {self.dtype!r}"
            )


_ARRAY_HEAD = re.compile(r"(?P<name>[A-Za-z_]\w*)(?::(?P<dtype>\w+))?$")


def array_table(table: str) -> tuple[ArrayField, ...]:
    """The arrays of a record written as a table, one a line: ``NAME  MEANING``, ``NAME`` with
    its dtype after a colon where it is not float64 (``kids:int64``); a deeper-indented line
    continues the meaning (:func:`langenv.layout.field_table`'s form).

    Raises:
        ConfigError: naming the line, for a malformed name, a continuation before any array or
            an unknown dtype.
    """
    rows = table_rows(table, _ARRAY_HEAD, "NAME:DTYPE")
    return tuple(ArrayField(m["name"], m["dtype"] or "float64", doc) for m, doc in rows)


class Record:
    """Arrays declared once, reached by address: each one's address and length (2-D arrays:
    their number of entries) in an int64 row.

    Args:
        name: The record's name.
        parts: Tuples of :class:`ArrayField` or other records, in order (a record's rows start
            with those of the records it is composed of, so a kernel of a part may take it).
    """

    def __init__(self, name: str, *parts: Iterable[ArrayField] | Record) -> None:
        arrays: list[ArrayField] = []
        for part in parts:
            arrays.extend(part.arrays if isinstance(part, Record) else part)
        fields = []
        for a in arrays:
            fields.append(Field(a.name, kind="int", doc=f"the address of {a.doc} ({a.dtype})"))
            fields.append(Field(f"{a.name}_n", kind="int", doc=f"the entries of ``{a.name}``"))
        self.layout = Layout(name, tuple(fields))
        self.name = name
        self.arrays: tuple[ArrayField, ...] = tuple(arrays)
        self.size: int = self.layout.size
        self.at: Any = self.layout.at
        """Each array's slot (its address; its length follows), as :attr:`Layout.at
        <langenv.layout.Layout.at>`: ``f8(row, RECORD.at.ws)``."""

    def __repr__(self) -> str:
        return f"Record({self.name!r}, {len(self.arrays)} arrays)"

    def zeros(self, n: int | None = None) -> np.ndarray:
        """A zeroed int64 row (``n``: a table of ``n`` rows)."""
        return np.zeros(self.size if n is None else (n, self.size), np.int64)

    def pack(self, out: np.ndarray, arrays: Mapping[str, np.ndarray]) -> np.ndarray:
        """Write ``arrays`` (every declared name, each C-contiguous of its dtype) into ``out``
        (int64); returns it.

        Raises:
            ConfigError: for a missing or unknown name, or an array of another dtype or not
                contiguous.
        """
        names = {a.name for a in self.arrays}
        if set(arrays) != names:
            missing, unknown = sorted(names - set(arrays)), sorted(set(arrays) - names)
            raise ConfigError(f"record {self.name!r}: missing {missing}, unknown {unknown}")
        for a in self.arrays:
            arr = arrays[a.name]
            out[self.layout.slot(a.name)] = address(arr, a.dtype) if arr.size else 0
            out[self.layout.slot(f"{a.name}_n")] = arr.size
        return out

    def table(self) -> str:
        """The record as a Markdown table (:meth:`Layout.table <langenv.layout.Layout.table>`)."""
        return self.layout.table()


def address(arr: np.ndarray, dtype: Any) -> int:
    """The address of ``arr``'s data, checked: C-contiguous, of ``dtype``."""
    if not isinstance(arr, np.ndarray) or arr.dtype != np.dtype(dtype):
        got = arr.dtype if isinstance(arr, np.ndarray) else type(arr).__name__
        raise ConfigError(f"expected a C-contiguous {np.dtype(dtype)} array, got {got}")
    if not arr.flags.c_contiguous:
        raise ConfigError(f"expected a C-contiguous {np.dtype(dtype)} array, got a strided one")
    return int(arr.ctypes.data)


def _view(dtype: Any, ndim: int) -> Any:
    """An intrinsic ``(address, *shape) -> array``: a C-contiguous view, no owner (emitted in
    the caller: no call, no reference count)."""
    arrty = types.Array(dtype, ndim, "C")

    def impl(typingctx: Any, addr: Any, *shape: Any) -> Any:
        sig = arrty(types.int64, *([types.int64] * ndim))

        def codegen(context: Any, builder: Any, signature: Any, args: Any) -> Any:
            ary = make_array(arrty)(context, builder)
            data = builder.inttoptr(args[0], context.get_value_type(dtype).as_pointer())
            itemsize = context.get_constant(
                types.intp, context.get_abi_sizeof(context.get_data_type(dtype))
            )
            dims = list(args[1:])
            strides = [itemsize] * ndim
            for i in range(ndim - 2, -1, -1):
                strides[i] = builder.mul(strides[i + 1], dims[i + 1])
            populate_array(
                ary, data=data, shape=dims, strides=strides, itemsize=itemsize, meminfo=None
            )
            return ary._getvalue()

        return sig, codegen

    return impl


def _f8_view(typingctx: Any, addr: Any, n: Any) -> Any:
    return _view(types.float64, 1)(typingctx, addr, n)


def _f8_2_view(typingctx: Any, addr: Any, rows: Any, cols: Any) -> Any:
    return _view(types.float64, 2)(typingctx, addr, rows, cols)


def _i8_view(typingctx: Any, addr: Any, n: Any) -> Any:
    return _view(types.int64, 1)(typingctx, addr, n)


def _f4_2_view(typingctx: Any, addr: Any, rows: Any, cols: Any) -> Any:
    return _view(types.float32, 2)(typingctx, addr, rows, cols)


_f8: Any = intrinsic(_f8_view)
_f8_2: Any = intrinsic(_f8_2_view)
_i8: Any = intrinsic(_i8_view)
_f4_2: Any = intrinsic(_f4_2_view)


@inline
def f8(row: np.ndarray, k: int) -> np.ndarray:
    """The float64 array of a record's row: address ``row[k]``, ``row[k + 1]`` entries (``k``:
    the array's slot, ``RECORD.at.<name>``)."""
    return _f8(row[k], row[k + 1])


@inline
def i8(row: np.ndarray, k: int) -> np.ndarray:
    """The int64 array of a record's row (see :func:`f8`)."""
    return _i8(row[k], row[k + 1])


@inline
def f8_2(row: np.ndarray, k: int, cols: int) -> np.ndarray:
    """The float64 2-D array of a record's row, ``cols`` entries a row (see :func:`f8`)."""
    return _f8_2(row[k], row[k + 1] // cols, cols)


@inline
def f4_2(row: np.ndarray, k: int, cols: int) -> np.ndarray:
    """The float32 2-D array of a record's row, ``cols`` entries a row (see :func:`f8`)."""
    return _f4_2(row[k], row[k + 1] // cols, cols)
