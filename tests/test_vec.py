"""langenv.vec: fixed-order dot products and norms (what the compiled kernels compute)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from langenv import vec
from langenv.kernels.blas import dot as kernel_dot

pytestmark = pytest.mark.portable

finite = st.floats(-1e6, 1e6, allow_nan=False, allow_infinity=False)


def _pair(n: int) -> st.SearchStrategy[tuple[np.ndarray, np.ndarray]]:
    return st.tuples(arrays(np.float64, n, elements=finite), arrays(np.float64, n, elements=finite))


@given(st.integers(1, 12).flatmap(_pair))
def test_dot_sums_left_to_right_within_the_rounding_bound(
    ab: tuple[np.ndarray, np.ndarray],
) -> None:
    a, b = ab
    s = 0.0
    for x, y in zip(a.tolist(), b.tolist(), strict=True):
        s += x * y
    assert vec.dot(a, b) == s  # the order is the promise, to the bit
    products = [x * y for x, y in zip(a.tolist(), b.tolist(), strict=True)]
    bound = len(products) * 2.3e-16 * math.fsum(abs(p) for p in products) + 1e-300
    assert abs(vec.dot(a, b) - math.fsum(products)) <= bound
    assert vec.dot(a, b) == vec.dot(b, a)


@settings(deadline=None)  # the first example loads the compiled kernel
@given(st.integers(1, 3).flatmap(_pair))
def test_short_dots_equal_the_kernels(ab: tuple[np.ndarray, np.ndarray]) -> None:
    a, b = ab
    assert vec.dot(a, b) == kernel_dot(a, 0, b, 0, a.size)


@given(arrays(np.float64, st.integers(0, 9), elements=finite))
def test_sumsq_and_norm(a: np.ndarray) -> None:
    assert vec.sumsq(a) == vec.dot(a, a)
    assert vec.norm(a) == math.sqrt(vec.sumsq(a))
    # squares below 1e-308 underflow (as in the kernels): hypot only to an absolute 1e-150
    assert vec.norm(a) == pytest.approx(math.hypot(*a.tolist()), rel=1e-14, abs=1e-150)
