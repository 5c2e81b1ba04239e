"""Trajectory geometry: arc-length parametrisation, tangents, curvature, local closest point."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from langenv.control.trajectory import (
    EXERCISE_ANGLE_DEG,
    ArcSegment,
    LineSegment,
    Trajectory,
    default_exercise,
    line,
)
from langenv.errors import ConfigError, TrajectoryError

EX = default_exercise()
L0, L1, L2 = (float(v) for v in np.diff(np.concatenate([[0.0], EX.waypoint_s])))
ANGLE = math.radians(EXERCISE_ANGLE_DEG)


def _interior_s(traj: Trajectory, n: int, margin: float = 1e-4) -> np.ndarray:
    """Arc lengths away from the segment joints."""
    s = np.linspace(0.0, traj.length, n)
    joints = np.concatenate([traj.seg_start, [traj.length]])
    keep = np.min(np.abs(s[:, None] - joints[None, :]), axis=1) > margin
    return s[keep]


def test_default_exercise_geometry() -> None:
    start = np.array([-0.350, -0.6206, 0.04])
    pivot = np.array([-0.400, -0.256, 0.0])
    np.testing.assert_allclose(EX.position(0.0), start, atol=1e-12)
    np.testing.assert_allclose(EX.position(EX.length), EX.position(L0), atol=1e-12)
    # arc, line back to the start, the same arc again
    radius = math.hypot(*(start - pivot)[:2])
    assert radius == pytest.approx(0.368, abs=1e-3)
    assert L0 == pytest.approx(radius * ANGLE, rel=1e-12)
    assert L2 == pytest.approx(L0, rel=1e-12)
    assert L1 == pytest.approx(2 * radius * math.sin(ANGLE / 2), rel=1e-9)
    np.testing.assert_allclose(EX.position(L0 + L1), start, atol=1e-12)
    # each segment is a leg, the last one ends at L
    np.testing.assert_allclose(EX.waypoint_s, [L0, L0 + L1, EX.length])
    # every point of the arcs is at the radius from the vertical axis, at the start's height
    for s in np.linspace(0.0, L0, 9):
        p = EX.position(float(s))
        assert math.hypot(*(p - pivot)[:2]) == pytest.approx(radius, abs=1e-12)
        assert p[2] == pytest.approx(0.04, abs=1e-12)
    # rotation sense: outwards to +x (documented in default_exercise), counter-clockwise from above
    end = EX.position(L0)
    assert end[0] > start[0] + 0.2
    assert np.cross(start - pivot, end - pivot)[2] > 0.0
    # the arc segment rotates by the fitted angle
    seg = EX.segments[0]
    assert isinstance(seg, ArcSegment)
    assert seg.angle == pytest.approx(ANGLE)
    # the tool turns with the arcs and back along the line
    assert [s.turn for s in EX.segments] == pytest.approx([ANGLE] * 3)
    assert EX.tool_angle(0.0) == 0.0
    assert EX.tool_angle(L0) == pytest.approx(ANGLE)
    assert EX.tool_angle(EX.length) == pytest.approx(3 * ANGLE)
    assert EX.turn_rate(L0, arriving=True) == pytest.approx(ANGLE / L0)
    assert EX.turn_rate(L0) == pytest.approx(ANGLE / L1)


def test_default_exercise_angle_argument() -> None:
    tr = default_exercise(50.0)
    assert tr.segments[0].length == pytest.approx(0.3683 * math.radians(50.0), rel=1e-3)
    for bad in (0.0, -5.0, 91.0, math.nan):
        with pytest.raises(TrajectoryError, match="angle_deg"):
            default_exercise(bad)


@given(st.floats(0.0, 1.0), st.floats(0.0, 1.0))
def test_tool_angle_is_monotone(a: float, b: float) -> None:
    lo, hi = sorted((a * EX.length, b * EX.length))
    assert EX.tool_angle(lo) <= EX.tool_angle(hi) + 1e-12


def test_arc_length_parametrisation_unit_speed() -> None:
    h = 1e-6
    for s in _interior_s(EX, 400, margin=2 * h):
        d = (EX.position(s + h) - EX.position(s - h)) / (2 * h)
        assert np.linalg.norm(d) == pytest.approx(1.0, abs=1e-6)


def test_tangent_and_curvature_match_finite_differences() -> None:
    h = 1e-5
    for s in _interior_s(EX, 200, margin=2 * h):
        d1 = (EX.position(s + h) - EX.position(s - h)) / (2 * h)
        d2 = (EX.position(s + h) - 2 * EX.position(s) + EX.position(s - h)) / h**2
        np.testing.assert_allclose(EX.tangent(s), d1, atol=1e-7)
        np.testing.assert_allclose(EX.curvature(s), d2, atol=2e-4)
        assert np.linalg.norm(EX.tangent(s)) == pytest.approx(1.0, abs=1e-12)
    radius = EX.segments[0].radius  # type: ignore[union-attr]
    assert np.linalg.norm(EX.curvature(0.1)) == pytest.approx(1.0 / radius)
    assert np.linalg.norm(EX.curvature(L0 + 0.1)) == 0.0


def test_tangent_is_the_right_derivative_at_joints() -> None:
    # at the end of the outbound arc the right derivative is the direction of the line back
    back = EX.position(L0 + L1) - EX.position(L0)
    np.testing.assert_allclose(EX.tangent(L0), back / np.linalg.norm(back), atol=1e-12)
    assert EX.segment_index(L0, "right") == 1
    assert EX.segment_index(L0, "left") == 0


def test_sample_shape_and_ends() -> None:
    pts = EX.sample(50)
    assert pts.shape == (50, 3)
    np.testing.assert_allclose(pts[0], EX.position(0.0))
    np.testing.assert_allclose(pts[-1], EX.position(EX.length))
    with pytest.raises(TrajectoryError, match="n"):
        EX.sample(1)


@settings(max_examples=200, deadline=None)
@given(
    s_true=st.floats(0.0, L0),
    ds_prev=st.floats(-0.03, 0.03),
    noise=st.tuples(*[st.floats(-0.007, 0.007)] * 3),
)
def test_closest_stays_on_the_outbound_leg(
    s_true: float, ds_prev: float, noise: tuple[float, float, float]
) -> None:
    """Started on the outbound arc, the search never jumps to the return arc over it."""
    x = EX.position(s_true) + np.array(noise)
    s_prev = min(max(s_true + ds_prev, 0.0), L0 - 1e-6)  # on the arc, not on its joint
    s = EX.closest(x, s_prev, 0.0, EX.length)  # whole trajectory allowed
    # the third segment is the same arc: a global argmin could land there, we must not
    assert s < L0 + 0.02
    assert np.linalg.norm(EX.position(s) - EX.position(s_true)) < 0.025
    # it is a local minimum of the distance: no better point nearby on the same leg (past the
    # corner the return line may be closer; the guide clamps the search at the stop there)
    d = np.linalg.norm(EX.position(s) - x)
    for ds in (-1e-3, 1e-3):
        s2 = min(max(s + ds, 0.0), L0)
        assert np.linalg.norm(EX.position(s2) - x) >= d - 1e-9


@settings(max_examples=100, deadline=None)
@given(s_true=st.floats(0.0, L0), noise=st.tuples(*[st.floats(-0.007, 0.007)] * 3))
def test_closest_on_the_return_arc_stays_there(
    s_true: float, noise: tuple[float, float, float]
) -> None:
    x = EX.position(s_true) + np.array(noise)
    s0 = L0 + L1
    s = EX.closest(x, s0 + s_true, 0.0, EX.length)
    assert s > s0 - 0.02
    assert np.linalg.norm(EX.position(s) - EX.position(s_true)) < 0.025


def test_closest_window_and_clamping() -> None:
    # past the end of the first arc, the search is clamped to the stop
    beyond = EX.position(L0) + 0.05 * EX.tangent(L0 - 1e-9)
    assert EX.closest(beyond, L0 - 0.01, 0.0, L0) == pytest.approx(L0)
    # behind the start of the line, clamped to its start
    behind = EX.position(L0) - 0.05 * EX.tangent(L0)
    assert EX.closest(behind, L0, L0, L0 + L1) == pytest.approx(L0)
    # a point on the line is found on the line
    mid = EX.position(L0 + 0.1)
    assert EX.closest(mid, L0, L0, L0 + L1) == pytest.approx(L0 + 0.1, abs=1e-9)
    with pytest.raises(TrajectoryError, match="window"):
        EX.closest(mid, 0.3, 0.4, 0.3)
    with pytest.raises(TrajectoryError, match="x"):
        EX.closest(np.array([np.nan, 0.0, 0.0]), 0.0)


def test_line_helper() -> None:
    tr = line([0, 0, 0], [1, 0, 0])
    assert tr.length == pytest.approx(1.0)
    np.testing.assert_allclose(tr.position(0.25), [0.25, 0, 0])
    np.testing.assert_allclose(tr.tangent(0.5), [1, 0, 0])
    np.testing.assert_allclose(tr.waypoint_s, [1.0])
    assert tr.closest(np.array([0.3, 0.2, -0.1]), 0.9) == pytest.approx(0.3)


def test_full_circle_and_negative_angle() -> None:
    arc = ArcSegment(
        center=np.zeros(3),
        axis=np.array([0, 0, 2.0]),
        start=np.array([1.0, 0, 0]),
        angle=-math.pi / 2,
    )
    np.testing.assert_allclose(arc.end, [0, -1, 0], atol=1e-12)
    tr = Trajectory([arc])
    np.testing.assert_allclose(tr.tangent(0.0), [0, -1, 0], atol=1e-12)
    np.testing.assert_allclose(tr.curvature(0.3), -tr.position(0.3), atol=1e-12)


@pytest.mark.parametrize(
    ("make", "field"),
    [
        (lambda: LineSegment(np.zeros(3), np.zeros(3)), "LineSegment.end"),
        (lambda: LineSegment(np.zeros(3), np.array([1.0, np.nan, 0])), "LineSegment.end"),
        (lambda: LineSegment(np.zeros(2), np.ones(3)), "LineSegment.start"),
        (lambda: LineSegment(np.zeros(3), np.array([np.inf, 0, 0])), "LineSegment.end"),
        (lambda: ArcSegment(np.zeros(3), np.zeros(3), np.ones(3), 1.0), "ArcSegment.axis"),
        (
            lambda: ArcSegment(np.zeros(3), np.array([0, 0, 1.0]), np.array([0, 0, 0.3]), 1.0),
            "ArcSegment.start",
        ),
        (
            lambda: ArcSegment(np.zeros(3), np.array([0, 0, 1.0]), np.ones(3), 0.0),
            "ArcSegment.angle",
        ),
        (
            lambda: ArcSegment(np.zeros(3), np.array([0, 0, 1.0]), np.ones(3), math.nan),
            "ArcSegment.angle",
        ),
        (
            lambda: ArcSegment(np.zeros(3), np.array([0, 0, 1.0]), np.ones(3), 7.0),
            "ArcSegment.angle",
        ),
        (
            lambda: ArcSegment(np.array([0, np.nan, 0]), np.array([0, 0, 1.0]), np.ones(3), 1.0),
            "ArcSegment.center",
        ),
        (lambda: Trajectory([]), "segments"),
        (
            lambda: Trajectory(
                [
                    LineSegment(np.zeros(3), np.ones(3)),
                    LineSegment(np.ones(3) * 1.01, np.ones(3) * 2),
                ]
            ),
            "segments\\[1\\]",
        ),
        (lambda: Trajectory(["not a segment"]), "segments\\[0\\]"),  # type: ignore[list-item]
        (lambda: LineSegment(np.zeros(3), np.ones(3), turn=-1.0), "LineSegment.turn"),
        (
            lambda: ArcSegment(np.zeros(3), np.array([0, 0, 1.0]), np.ones(3), 1.0, turn=math.inf),
            "ArcSegment.turn",
        ),
    ],
)
def test_validation_names_the_field(make: object, field: str) -> None:
    with pytest.raises(TrajectoryError, match=field):
        make()  # type: ignore[operator]


def test_errors_are_config_errors_and_arrays_are_read_only() -> None:
    assert issubclass(TrajectoryError, ConfigError)
    seg = LineSegment(np.zeros(3), np.ones(3))
    with pytest.raises(ValueError):
        seg.start[0] = 1.0
    with pytest.raises(TrajectoryError, match="finite"):
        EX.position(math.nan)


def test_closest_from_a_joint_starts_on_the_nearer_segment() -> None:
    """s_prev exactly on the arc/line joint: a point on the arc is found on the arc."""
    s_true = L0 - 0.02
    s = EX.closest(EX.position(s_true), L0, 0.0, EX.length)
    assert s == pytest.approx(s_true, abs=1e-6)
