"""MuJoCo's own C functions called from compiled code: ``mj_step2``, ``mj_step1``, ``mj_jacSite``.

The tick calls them through their addresses in the ``libmujoco`` that the ``mujoco`` package
loads (the same library, so the same functions on the same ``mjModel``/``mjData`` as the Python
bindings: bit-identical results), without a return to Python between the control law and the
physics. The addresses are arguments (an ``int64`` array, :func:`pointers`), not constants baked
into the code, so the compiled code stays cached on disk.

A fatal MuJoCo error (``mju_error``: no memory left in ``mjData``'s arena) cannot be raised as a
Python exception from compiled code; the bindings print it and the process ends. The arm's model
allocates enough for every contact it can have.
"""

from __future__ import annotations

import ctypes
import functools
from pathlib import Path
from typing import Any

import mujoco
import numpy as np
from llvmlite import ir
from numba import types
from numba.extending import intrinsic

from langenv.errors import ConfigError

__all__ = ["available", "call_jac", "call_md", "pointers"]

# slots of the pointer array
P_MODEL, P_DATA, P_STEP1, P_STEP2, P_JACSITE, P_JACP, P_JACR, P_SITE = range(8)
N_POINTERS = 8


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
    """Whether MuJoCo's library can be called from compiled code here."""
    try:
        _library()
    except (ConfigError, OSError):
        return False
    return True


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
    return out


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
