"""C functions called from compiled code: MuJoCo's ``mj_step2``, ``mj_step1``, ``mj_jacSite``;
the C library's ``pow``.

The tick calls them through their addresses in the ``libmujoco`` that the ``mujoco`` package
loads (the same library, so the same functions on the same ``mjModel``/``mjData`` as the Python
bindings: bit-identical results), without a return to Python between the control law and the
physics. The addresses are arguments (an ``int64`` array, :func:`pointers`), not constants baked
into the code, so the compiled code stays cached on disk. ``pow`` is the C library's, which
CPython's ``x ** y`` calls: compiled code that squares as Python does (``x ** 2`` is not always
``x * x`` in the last bit) calls it too (:func:`py_square`).

A fatal MuJoCo error (``mju_error``: no memory left in ``mjData``'s arena) cannot be raised as a
Python exception from compiled code; the bindings print it and the process ends. The arm's model
allocates enough for every contact it can have.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import functools
from pathlib import Path
from typing import Any

import mujoco
import numpy as np
from llvmlite import ir
from numba import types
from numba.extending import intrinsic

from langenv.errors import ConfigError
from langenv.kernels import kernel
from langenv.layout import Layout, field_table

__all__ = [
    "POINTERS",
    "available",
    "call_jac",
    "call_md",
    "call_pow",
    "pointers",
    "pow_address",
    "py_square",
]

POINTERS = Layout(
    "pointers",
    field_table(
        """
        model:int     the ``mjModel``
        data:int      the ``mjData``
        step1:int     ``mj_step1``
        step2:int     ``mj_step2``
        jac_site:int  ``mj_jacSite``
        jacp:int      the positional Jacobian's buffer
        jacr:int      the rotational Jacobian's buffer
        site:int      the handle site's id (a number, not an address)
        pow:int       the C library's ``pow``
        """
    ),
)
"""The addresses of :func:`pointers`' ``int64`` array, by name."""
_P = POINTERS.at
P_MODEL, P_DATA, P_STEP1, P_STEP2, P_JACSITE = _P.model, _P.data, _P.step1, _P.step2, _P.jac_site
P_JACP, P_JACR, P_SITE, P_POW = _P.jacp, _P.jacr, _P.site, _P.pow
N_POINTERS = POINTERS.size


@functools.cache
def _library() -> ctypes.CDLL:
    """The ``libmujoco`` shipped in the ``mujoco`` package (already loaded by its bindings)."""
    here = Path(mujoco.__file__).resolve().parent
    found = sorted(here.glob("libmujoco.so*")) + sorted(here.glob("libmujoco*.dylib"))
    found += sorted(here.glob("mujoco*.dll"))
    if not found:
        raise ConfigError(f"no libmujoco next to the mujoco package in {here}")
    return ctypes.CDLL(str(found[0]))


def available() -> bool:
    """Whether MuJoCo's library was found (else ``GuidedArm`` runs its Python tick)."""
    try:
        _library()
    except (ConfigError, OSError):
        return False
    return True


@functools.cache
def _libm() -> ctypes.CDLL:
    """The C math library (the one CPython's float ``**`` calls)."""
    name = ctypes.util.find_library("m")
    return ctypes.CDLL(name) if name else ctypes.CDLL(None)


def pointers(model: Any, data: Any, jacp: np.ndarray, jacr: np.ndarray, site: int) -> np.ndarray:
    """The addresses the compiled tick needs, as an ``int64`` array (keep the objects alive).

    Args:
        model, data: The ``mujoco.MjModel`` and ``mujoco.MjData`` stepped.
        jacp, jacr: C-contiguous float64 ``(3, nv)`` arrays ``mj_jacSite`` writes.
        site: The site's id.
    """
    for name, arr in (("jacp", jacp), ("jacr", jacr)):
        if arr.dtype != np.float64 or not arr.flags.c_contiguous:
            raise ConfigError(f"{name} must be a C-contiguous float64 array")
    lib = _library()
    out = np.zeros(N_POINTERS, np.int64)
    out[P_MODEL], out[P_DATA] = model._address, data._address
    for slot, name in ((P_STEP1, "mj_step1"), (P_STEP2, "mj_step2"), (P_JACSITE, "mj_jacSite")):
        out[slot] = int(ctypes.cast(getattr(lib, name), ctypes.c_void_p).value or 0)
    out[P_JACP], out[P_JACR] = jacp.ctypes.data, jacr.ctypes.data
    out[P_SITE] = site
    out[P_POW] = pow_address()
    return out


def pow_address() -> int:
    """The address of the C library's ``pow`` (for :func:`py_square`)."""
    return int(ctypes.cast(_libm().pow, ctypes.c_void_p).value or 0)


def _call_md(typingctx: Any, fn: Any, m: Any, d: Any) -> Any:
    """``fn(m, d)`` for a C function ``void fn(const mjModel*, mjData*)`` at address ``fn``."""
    sig = types.void(types.int64, types.int64, types.int64)

    def codegen(context: Any, builder: Any, signature: Any, args: Any) -> Any:
        ptr = ir.IntType(8).as_pointer()
        fnty = ir.FunctionType(ir.VoidType(), [ptr, ptr])
        f = builder.inttoptr(args[0], fnty.as_pointer())
        builder.call(f, [builder.inttoptr(args[1], ptr), builder.inttoptr(args[2], ptr)])
        return context.get_dummy_value()

    return sig, codegen


call_md: Any = intrinsic(_call_md)


def _call_jac(typingctx: Any, fn: Any, m: Any, d: Any, jacp: Any, jacr: Any, site: Any) -> Any:
    """``mj_jacSite(m, d, jacp, jacr, site)`` at address ``fn``."""
    sig = types.void(types.int64, types.int64, types.int64, types.int64, types.int64, types.int64)

    def codegen(context: Any, builder: Any, signature: Any, args: Any) -> Any:
        ptr = ir.IntType(8).as_pointer()
        dbl = ir.DoubleType().as_pointer()
        i32 = ir.IntType(32)
        fnty = ir.FunctionType(ir.VoidType(), [ptr, ptr, dbl, dbl, i32])
        f = builder.inttoptr(args[0], fnty.as_pointer())
        builder.call(
            f,
            [
                builder.inttoptr(args[1], ptr),
                builder.inttoptr(args[2], ptr),
                builder.inttoptr(args[3], dbl),
                builder.inttoptr(args[4], dbl),
                builder.trunc(args[5], i32),
            ],
        )
        return context.get_dummy_value()

    return sig, codegen


call_jac: Any = intrinsic(_call_jac)


def _call_pow(typingctx: Any, fn: Any, x: Any, y: Any) -> Any:
    """``pow(x, y)`` of the C library at address ``fn``."""
    sig = types.float64(types.int64, types.float64, types.float64)

    def codegen(context: Any, builder: Any, signature: Any, args: Any) -> Any:
        dbl = ir.DoubleType()
        fnty = ir.FunctionType(dbl, [dbl, dbl])
        f = builder.inttoptr(args[0], fnty.as_pointer())
        return builder.call(f, [args[1], args[2]])

    return sig, codegen


call_pow: Any = intrinsic(_call_pow)


@kernel
def py_square(fn: int, x: float) -> float:
    """CPython's ``x ** 2`` for a finite float ``x`` (``float_pow``: ``pow(|x|, 2.0)``)."""
    if x == 0.0:
        return 0.0
    ax = -x if x < 0.0 else x
    if ax == 1.0:
        return 1.0
    return float(call_pow(fn, ax, 2.0))
