"""Guide: virtual force, stops, feed-forward, and the nominal virtual run of the exercise."""

from __future__ import annotations

import numpy as np
import pytest

from langenv.control.admittance import AdmittanceParams
from langenv.control.guide import Guide, GuideState
from langenv.control.motion_etc import VirtualRun, simulate_virtual
from langenv.control.trajectory import default_exercise, line
from langenv.errors import ConfigError

EX = default_exercise()
P = AdmittanceParams()


@pytest.fixture(scope="module")
def nominal() -> VirtualRun:
    return simulate_virtual(EX, P)


def test_nominal_run_matches_the_study(nominal: VirtualRun) -> None:
    """F_ext = 0, p = 1: 10-12.5 s, plateau 0.11-0.14 m/s, within 1 cm of the path."""
    assert nominal.done_time is not None
    assert 10.0 <= nominal.done_time <= 12.5
    assert 0.11 <= nominal.max_speed <= 0.14
    assert nominal.max_path_error < 0.01
    # motion over at the end, at rest at the end point
    assert nominal.stop_index[-1] == len(EX.stop_s)
    assert np.linalg.norm(nominal.x[-1] - EX.position(EX.length)) < P.stop_tol_pos
    assert np.linalg.norm(nominal.v[-1]) < P.stop_tol_vel


def test_nominal_run_never_jumps_and_rests_at_each_stop(nominal: VirtualRun) -> None:
    ds = np.diff(nominal.s)
    speed = np.linalg.norm(nominal.v[1:], axis=1)
    # the closest point moves no faster than the hand (plus the small arc/offset effects)
    assert np.all(np.abs(ds) <= 1.1 * speed * 0.002 + 1e-9)
    assert np.all(ds >= -1e-9)  # and, guided without resistance, never backwards
    # each stop is reached at rest, in order
    switch = np.nonzero(np.diff(nominal.stop_index))[0] + 1
    assert len(switch) == len(EX.stop_s)
    for k, i in enumerate(switch):
        assert np.linalg.norm(nominal.x[i] - EX.position(EX.stop_s[k])) < P.stop_tol_pos
        assert np.linalg.norm(nominal.v[i]) < P.stop_tol_vel
    # the three segments take similar times (same 1D dynamics on each)
    seg_times = np.diff(np.concatenate([[0.0], nominal.t[switch]]))
    assert np.ptp(seg_times) < 0.1


def test_curvature_feedforward_keeps_the_hand_on_the_arc(nominal: VirtualRun) -> None:
    without = simulate_virtual(EX, AdmittanceParams(curvature_feedforward=False))
    # without it the spring supplies the centripetal force from a lateral offset ~ M0 v^2/(R K)
    assert without.max_path_error > 0.008
    assert nominal.max_path_error < 0.4 * without.max_path_error


def test_constant_pace_warps_time() -> None:
    """The closed loop at constant p is the nominal one in warped time: t_done ~ T / p."""
    base = simulate_virtual(EX, P).done_time
    fast = simulate_virtual(EX, P, p=1.25).done_time
    assert base is not None and fast is not None
    # the stop rule (|v| < tol) is not warp-invariant, hence the small tolerance
    assert fast == pytest.approx(base / 1.25, rel=0.03)


def test_virtual_force_components() -> None:
    tr = line([0.0, 0.0, 0.0], [1.0, 0.0, 0.0])
    guide = Guide(tr, P)
    st = guide.initial_state()
    x = np.array([0.3, 0.02, -0.01])
    guide.update(st, x, np.zeros(3))
    assert st.s == pytest.approx(0.3)
    f = guide.virtual_force(st, x, np.zeros(3), 1.0)
    np.testing.assert_allclose(f, [P.propel_force, -P.stiffness * 0.02, P.stiffness * 0.01])
    # linear taper over the braking distance
    for rem in (0.15, 0.1, 0.075, 0.01):
        xs = np.array([1.0 - rem, 0.0, 0.0])
        st = GuideState(1.0 - rem, 0, False)
        f = guide.virtual_force(st, xs, np.zeros(3), 1.0)
        assert f[0] == pytest.approx(P.propel_force * rem / P.brake_distance)
    # past the stop the closest point is clamped: the spring pulls back to the end point
    past = np.array([1.03, 0.01, 0.0])
    st = GuideState(0.99, 0, False)
    guide.update(st, past, np.array([0.05, 0.0, 0.0]))
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


def test_stop_reached_only_at_rest_and_close() -> None:
    tr = line([0.0, 0.0, 0.0], [0.5, 0.0, 0.0])
    guide = Guide(tr, P)
    end = np.array([0.5, 0.0, 0.0])
    st = GuideState(0.49, 0, False)
    guide.update(st, end + np.array([0.0, 0.006, 0.0]), np.zeros(3))  # 6 mm off: not yet
    assert not st.done
    guide.update(st, end, np.array([0.011, 0.0, 0.0]))  # too fast: not yet
    assert not st.done
    guide.update(st, end + np.array([-0.003, 0.002, 0.0]), np.array([0.005, 0.005, 0.0]))
    assert st.done and st.s == pytest.approx(0.5) and st.stop_index == 1
    # once done only the spring to the end point remains; update is a no-op
    x = end + np.array([0.0, 0.01, 0.0])
    np.testing.assert_allclose(
        guide.virtual_force(st, x, np.ones(3), 1.0), [0.0, -P.stiffness * 0.01, 0.0]
    )
    guide.update(st, np.zeros(3), np.zeros(3))
    assert st.done and st.s == pytest.approx(0.5)


def test_stops_advance_the_window() -> None:
    guide = Guide(EX, P)
    st = guide.initial_state()
    s0 = float(EX.stop_s[0])
    assert guide.window(st) == (0.0, s0)
    guide.update(st, EX.position(s0), np.zeros(3))
    assert st.stop_index == 1 and st.s == pytest.approx(s0) and not st.done
    assert guide.window(st) == (s0, float(EX.stop_s[1]))
    # the new segment starts with the full propelling force along the line back
    f = guide.virtual_force(st, EX.position(s0), np.zeros(3), 1.0)
    np.testing.assert_allclose(f, P.propel_force * EX.tangent(s0), atol=1e-12)
    # the closest point now searches the line, not the arc the hand came from
    x = EX.position(s0 + 0.05)
    guide.update(st, x, 0.1 * EX.tangent(s0))
    assert st.s == pytest.approx(s0 + 0.05, abs=1e-9)


def test_tangent_is_the_direction_of_travel() -> None:
    guide = Guide(EX, P)
    s0 = float(EX.stop_s[0])
    clamped = GuideState(s0, 0, False)  # closest point clamped at the stop, not reached yet
    np.testing.assert_allclose(guide.tangent(clamped), EX.tangent(s0 - 1e-12), atol=1e-9)
    reached = GuideState(s0, 1, False)
    np.testing.assert_allclose(guide.tangent(reached), EX.tangent(s0), atol=1e-12)


def test_state_copy_is_independent() -> None:
    st = GuideState(0.1, 0, False)
    cp = st.copy()
    cp.s, cp.stop_index, cp.done = 0.2, 1, True
    assert (st.s, st.stop_index, st.done) == (0.1, 0, False)


def test_guide_validates_its_arguments() -> None:
    with pytest.raises(ConfigError, match="trajectory"):
        Guide("exercise", P)  # type: ignore[arg-type]
    with pytest.raises(ConfigError, match="params"):
        Guide(EX, None)  # type: ignore[arg-type]
