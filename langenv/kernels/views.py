"""Arrays by address in compiled code: a batch's kernels reach each session's arrays (kept
alive by the session's own objects) through one table of addresses instead of one argument per
array (:mod:`langenv.batch.kernels`).

:func:`address` gives a C-contiguous array's address; in compiled code :func:`f8`, :func:`f8_2`,
:func:`i8` and :func:`f4_2` turn an address and a shape back into an array view (``numba.carray``:
no copy, no reference count: a view owns nothing). The caller keeps the arrays alive and their
shapes unchanged while the views are used. They return arrays, so they are compiled with Numba's
reference counting (:func:`~langenv.kernels.jit`), as their callers must be; the hot path's
kernels they feed need none.
"""

from __future__ import annotations

from typing import Any

import numba
import numpy as np
from llvmlite import ir
from numba import types
from numba.extending import intrinsic

from langenv.errors import ConfigError
from langenv.kernels import jit

__all__ = ["address", "f4_2", "f8", "f8_2", "i8"]


def address(arr: np.ndarray, dtype: Any) -> int:
    """The address of ``arr``'s data, checked: C-contiguous, of ``dtype``."""
    if arr.dtype != np.dtype(dtype) or not arr.flags.c_contiguous:
        raise ConfigError(f"expected a C-contiguous {np.dtype(dtype)} array, got {arr.dtype}")
    return int(arr.ctypes.data)


def _pointer(target: Any) -> Any:
    def impl(typingctx: Any, addr: Any) -> Any:
        sig = types.CPointer(target)(types.int64)

        def codegen(context: Any, builder: Any, signature: Any, args: Any) -> Any:
            llty = context.get_value_type(target).as_pointer()
            return builder.inttoptr(args[0], llty)

        return sig, codegen

    return intrinsic(impl)


_f8p: Any = _pointer(types.float64)
_f4p: Any = _pointer(types.float32)
_i8p: Any = _pointer(types.int64)
_ = ir  # llvmlite is what the intrinsics emit


@jit
def f8(addr: int, n: int) -> np.ndarray:
    """A float64 ``(n,)`` view of the array at ``addr``."""
    return numba.carray(_f8p(addr), (n,))


@jit
def f8_2(addr: int, rows: int, cols: int) -> np.ndarray:
    """A float64 ``(rows, cols)`` view of the array at ``addr``."""
    return numba.carray(_f8p(addr), (rows, cols))


@jit
def i8(addr: int, n: int) -> np.ndarray:
    """An int64 ``(n,)`` view of the array at ``addr``."""
    return numba.carray(_i8p(addr), (n,))


@jit
def f4_2(addr: int, rows: int, cols: int) -> np.ndarray:
    """A float32 ``(rows, cols)`` view of the array at ``addr``."""
    return numba.carray(_f4p(addr), (rows, cols))
