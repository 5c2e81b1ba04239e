"""Splines as lines and arcs: biarcs join ends and tangents; the fit keeps its tolerance."""

from __future__ import annotations

import itertools
import math

import numpy as np
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from langenv.errors import TrajectoryError
from langenv.exercise.curves import arc_to, biarc, fit_spline, spline_points

coord = st.floats(-0.5, 0.5, allow_nan=False)
vec = st.tuples(coord, coord, coord).map(np.array)


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v)


def _tangent(seg: object, at_end: bool) -> np.ndarray:
    return np.array(seg.unit_tangent(seg.length if at_end else 0.0))  # type: ignore[attr-defined]


@settings(max_examples=200, deadline=None)
@given(vec, vec, vec, vec)
def test_a_biarc_leaves_and_arrives_along_the_tangents(
    p0: np.ndarray, d0: np.ndarray, p1: np.ndarray, d1: np.ndarray
) -> None:
    assume(np.linalg.norm(d0) > 0.05 and np.linalg.norm(d1) > 0.05)
    assume(np.linalg.norm(p1 - p0) > 0.02)
    t0, t1 = _unit(d0), _unit(d1)
    assume(float((p1 - p0) @ (t0 + t1)) > 1e-3)  # both tangents roughly towards the chord
    first, second = biarc(p0, t0, p1, t1)
    np.testing.assert_allclose(first.start, p0, atol=1e-9)
    np.testing.assert_allclose(_tangent(first, False), t0, atol=1e-6)
    np.testing.assert_allclose(second.start, first.end, atol=1e-12)
    np.testing.assert_allclose(_tangent(second, False), _tangent(first, True), atol=1e-6)
    np.testing.assert_allclose(second.end, p1, atol=1e-7)
    np.testing.assert_allclose(_tangent(second, True), t1, atol=1e-5)


@settings(max_examples=100, deadline=None)
@given(vec, vec, vec)
def test_arc_to_reaches_its_end(p0: np.ndarray, d0: np.ndarray, p1: np.ndarray) -> None:
    assume(np.linalg.norm(d0) > 0.05 and np.linalg.norm(p1 - p0) > 0.02)
    t0 = _unit(d0)
    assume(float((p1 - p0) @ t0) > -0.9 * np.linalg.norm(p1 - p0))  # not straight behind
    seg = arc_to(p0, t0, p1)
    np.testing.assert_allclose(seg.end, p1, atol=1e-7)
    np.testing.assert_allclose(_tangent(seg, False), t0, atol=1e-6)


@settings(max_examples=40, deadline=None)
@given(
    st.lists(st.tuples(coord, coord, st.floats(0.0, 0.4)), min_size=1, max_size=4),
    st.sampled_from([1e-4, 1e-3, 5e-3]),
)
def test_the_fit_stays_within_its_tolerance_of_the_spline(
    points: list[tuple[float, float, float]], tol: float
) -> None:
    start = np.array([-0.3, -0.5, 0.1])
    pts = np.array(points)
    chain = np.vstack([start, pts])
    assume(np.min(np.linalg.norm(np.diff(chain, axis=0), axis=1)) > 0.05)
    try:
        segs = fit_spline(start, pts, tol)
    except TrajectoryError:  # a cusp the biarcs cannot follow is refused, not wrong
        assume(False)
        return
    np.testing.assert_allclose(segs[-1].end, pts[-1], atol=1e-7)
    for a, b in itertools.pairwise(segs):
        np.testing.assert_allclose(b.start, a.end, atol=1e-12)
        assert float(_tangent(a, True) @ _tangent(b, False)) > math.cos(math.radians(0.5))
    knots, spline = spline_points(start, pts)
    dense = np.asarray(spline(np.linspace(0.0, knots[-1], 400)))  # type: ignore[operator]
    worst = max(min(math.dist(x, s.point(s.project(*x))) for s in segs) for x in dense.tolist())
    assert worst <= 1.5 * tol  # checked at 24 points per piece; between them a little more
