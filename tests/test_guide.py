"""Guide: virtual force, leg switching (the lab's rule), feed-forward, and the nominal virtual run."""

from __future__ import annotations

import math

import numpy as np
import pytest

from langenv.control.admittance import AdmittanceParams
from langenv.control.guide import Guide, GuideState
from langenv.control.trajectory import default_exercise, line
from langenv.control.virtual_loop import VirtualRun, simulate_virtual
from langenv.errors import ConfigError

EX = default_exercise()
P = AdmittanceParams()
EXACT = AdmittanceParams(max_acceleration=math.inf)  # the hand tracks v_ref exactly


@pytest.fixture(scope="module")
def nominal() -> VirtualRun:
    return simulate_virtual(EX, P)


def _path_distance(x: np.ndarray) -> float:
    """Distance from ``x`` to the nearest point of the exercise path (any segment)."""
    return min(
        float(np.linalg.norm(x - np.array(seg.point(seg.project(*x.tolist())))))
        for seg in EX.segments
    )


def test_nominal_run_matches_the_recordings(nominal: VirtualRun) -> None:
    """F_ext = 0, p = 1: the recordings' ~10-11 s, plateaus near 0.125 m/s, legs of ~3.4 s."""
    assert nominal.done_time is not None
    assert 9.5 <= nominal.done_time <= 12.5
    assert 0.11 <= nominal.max_speed <= 0.14
    switch = np.flatnonzero(np.diff(nominal.leg)) + 1
    assert len(switch) == EX.waypoint_s.size
    legs = np.diff(np.concatenate([[0.0], nominal.t[switch]]))
    assert np.all((legs > 2.3) & (legs < 3.6))
    # the hand never comes to rest between legs: no stops, only V-shaped dips
    moving = nominal.t < nominal.t[switch[-1]]
    assert np.linalg.norm(nominal.v[moving][50:], axis=1).min() > 0.005
    # motion over: braked to rest (the last row is the last tick of braking), near the end
    assert np.linalg.norm(nominal.v[-1]) <= P.max_acceleration * 0.002 + 1e-12
    assert np.linalg.norm(nominal.x[-1] - EX.position(EX.length)) < 0.05


def test_nominal_run_stays_near_the_path(nominal: VirtualRun) -> None:
    """Along the legs the hand stays within 1 cm of the path; at the corners it overshoots by
    ~2 cm (it brakes at 0.14 m/s^2 from 3.5 cm before the end) and then settles back."""
    dist = np.array([_path_distance(x) for x in nominal.x])
    assert dist.max() < 0.03
    mid_leg = (
        np.abs(nominal.s[:, None] - np.concatenate([[0.0], EX.waypoint_s])[None, :]).min(axis=1)
        > 0.08
    )
    assert dist[mid_leg].max() < 0.01


def test_legs_switch_early_without_waiting(nominal: VirtualRun) -> None:
    guide = Guide(EX, P)
    switch = np.flatnonzero(np.diff(nominal.leg)) + 1
    for k, i in enumerate(switch):
        end = EX.position(EX.waypoint_s[k])
        # at the switch the hand is about 3.5 cm before the end point, still at full speed
        assert np.linalg.norm(nominal.x[i] - end) == pytest.approx(
            guide.switch_distance(k), abs=0.003
        )
        assert np.linalg.norm(nominal.v[i]) > 0.11


def test_switch_distance_is_the_lab_tolerance_in_6d() -> None:
    guide = Guide(EX, P)
    for k in range(guide.n_legs):
        end = float(EX.waypoint_s[k])
        q = guide.switch_distance(k)
        # on the path q before the end the 6-D distance sqrt(q^2 + dphi^2) is the tolerance
        dphi = EX.tool_angle(end) - EX.tool_angle(end - q)
        assert math.hypot(q, dphi) == pytest.approx(P.switch_tol, rel=1e-9)
        assert 0.03 < q < 0.04


def test_curvature_feedforward_keeps_the_hand_on_the_arc() -> None:
    with_ff = simulate_virtual(EX, EXACT)
    without = simulate_virtual(
        EX, AdmittanceParams(max_acceleration=math.inf, curvature_feedforward=False)
    )
    on_arc = (with_ff.leg == 0) & (with_ff.s > 0.05) & (with_ff.s < EX.waypoint_s[0] - 0.05)
    off_arc = (without.leg == 0) & (without.s > 0.05) & (without.s < EX.waypoint_s[0] - 0.05)
    # without it the spring supplies the centripetal force from a lateral offset ~ M0 v^2/(R K)
    assert without.path_error[off_arc].max() > 0.008
    assert with_ff.path_error[on_arc].max() < 0.4 * without.path_error[off_arc].max()


def test_constant_pace_warps_time() -> None:
    """With exact tracking the closed loop at constant p is the nominal one in warped time."""
    base = simulate_virtual(EX, EXACT).done_time
    fast = simulate_virtual(EX, EXACT, p=1.25).done_time
    assert base is not None and fast is not None
    assert fast == pytest.approx(base / 1.25, rel=0.01)


def test_virtual_force_components() -> None:
    tr = line([0.0, 0.0, 0.0], [1.0, 0.0, 0.0])
    guide = Guide(tr, P)
    st = guide.initial_state()
    x = np.array([0.3, 0.02, -0.01])
    guide.update(st, x)
    assert st.s == pytest.approx(0.3)
    f = guide.virtual_force(st, x, np.zeros(3), 1.0)
    np.testing.assert_allclose(f, [P.propel_force, -P.stiffness * 0.02, P.stiffness * 0.01])
    # no taper: the full propelling force right up to the end
    for rem in (0.15, 0.05, 0.01):
        xs = np.array([1.0 - rem, 0.0, 0.0])
        st = GuideState(1.0 - rem, 0, False)
        assert guide.virtual_force(st, xs, np.zeros(3), 1.0)[0] == pytest.approx(P.propel_force)
    # past the end (off the path, so not switched): the spring pulls back to the end point
    past = np.array([1.03, 0.2, 0.0])
    st = GuideState(0.99, 0, False)
    guide.update(st, past)
    assert st.s == pytest.approx(1.0) and not st.done
    np.testing.assert_allclose(
        guide.virtual_force(st, past, np.zeros(3), 1.0),
        P.stiffness * (np.array([1.0, 0, 0]) - past),
    )


def test_centripetal_feedforward_value() -> None:
    guide = Guide(EX, P)
    s = 0.1
    st = GuideState(s, 0, False)
    x = EX.position(s)
    b = EX.tangent(s)
    kappa = EX.curvature(s)
    for p in (1.0, 1.4, 0.6):
        v = 0.1 * b
        f = guide.virtual_force(st, x, v, p)
        expected = P.propel_force * b + P.mass * kappa * (0.1 / p) ** 2
        np.testing.assert_allclose(f, expected, atol=1e-12)
    off = Guide(EX, AdmittanceParams(curvature_feedforward=False))
    np.testing.assert_allclose(off.virtual_force(st, x, 0.1 * b, 1.0), P.propel_force * b)


def test_leg_ends_when_the_pose_is_close_whatever_the_speed() -> None:
    tr = line([0.0, 0.0, 0.0], [0.5, 0.0, 0.0])  # no tool turn: the 6-D distance is positional
    guide = Guide(tr, P)
    end = np.array([0.5, 0.0, 0.0])
    st = GuideState(0.3, 0, False)
    guide.update(st, end - np.array([0.101, 0.0, 0.0]))  # 10.1 cm before: not yet
    assert not st.done and st.leg == 0
    guide.update(st, end - np.array([0.061, 0.08, 0.0]))  # 10.06 cm away, off the path
    assert not st.done
    guide.update(st, end - np.array([0.099, 0.0, 0.0]))  # within 0.1: done, at any speed
    assert st.done and st.leg == 1 and st.s == pytest.approx(0.5)
    # once done only the spring to the end point remains; update is a no-op
    x = end + np.array([0.0, 0.01, 0.0])
    np.testing.assert_allclose(
        guide.virtual_force(st, x, np.ones(3), 1.0), [0.0, -P.stiffness * 0.01, 0.0]
    )
    guide.update(st, np.zeros(3))
    assert st.done and st.s == pytest.approx(0.5)


def test_switch_advances_the_window() -> None:
    guide = Guide(EX, P)
    st = guide.initial_state()
    s0 = float(EX.waypoint_s[0])
    assert guide.window(st) == (0.0, s0)
    guide.update(st, EX.position(s0 - 0.03))
    assert st.leg == 1 and not st.done
    assert guide.window(st) == (s0, float(EX.waypoint_s[1]))
    # the new leg starts with the full propelling force along the line back
    x = EX.position(s0 + 0.05)
    guide.update(st, x)
    assert st.s == pytest.approx(s0 + 0.05, abs=1e-9)
    f = guide.virtual_force(st, x, np.zeros(3), 1.0)
    np.testing.assert_allclose(f, P.propel_force * EX.tangent(s0), atol=1e-9)


def test_tangent_is_the_direction_of_travel() -> None:
    guide = Guide(EX, P)
    s0 = float(EX.waypoint_s[0])
    clamped = GuideState(s0, 0, False)  # closest point clamped at the leg's end, not switched
    np.testing.assert_allclose(guide.tangent(clamped), EX.tangent(s0 - 1e-12), atol=1e-9)
    switched = GuideState(s0, 1, False)
    np.testing.assert_allclose(guide.tangent(switched), EX.tangent(s0), atol=1e-12)


def test_state_copy_is_independent() -> None:
    st = GuideState(0.1, 0, False)
    cp = st.copy()
    cp.s, cp.leg, cp.done = 0.2, 1, True
    assert (st.s, st.leg, st.done) == (0.1, 0, False)


def test_guide_validates_its_arguments() -> None:
    with pytest.raises(ConfigError, match="trajectory"):
        Guide("exercise", P)  # type: ignore[arg-type]
    with pytest.raises(ConfigError, match="params"):
        Guide(EX, None)  # type: ignore[arg-type]
