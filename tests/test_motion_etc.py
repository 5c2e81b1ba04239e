"""Motion ETC: the 500 Hz reference and the fast estimator, on the nominal run and off it."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from bench.etc_agreement import etc_agreement, random_pace, random_resistance
from langenv.control import motion_etc
from langenv.control.admittance import AdmittanceParams, VariableAdmittance
from langenv.control.guide import Guide, GuideState
from langenv.control.motion_etc import FastETC, reference_etc
from langenv.control.trajectory import LineSegment, Trajectory, default_exercise, line
from langenv.control.virtual_loop import VirtualRun, simulate_virtual
from langenv.errors import ConfigError

EX = default_exercise()
P = AdmittanceParams()


@pytest.fixture(scope="module")
def guide() -> Guide:
    return Guide(EX, P)


@pytest.fixture(scope="module")
def adm() -> VariableAdmittance:
    return VariableAdmittance(P)


@pytest.fixture(scope="module")
def fast(guide: Guide, adm: VariableAdmittance) -> FastETC:
    return FastETC(guide, adm)


@pytest.fixture(scope="module")
def nominal() -> VirtualRun:
    return simulate_virtual(EX, P)


def test_reference_is_consistent_with_the_run(
    guide: Guide, adm: VariableAdmittance, nominal: VirtualRun
) -> None:
    """From any recorded state of the nominal run, the reference gives the time left exactly."""
    assert nominal.done_time is not None
    st = guide.initial_state()
    assert reference_etc(guide, adm, st, EX.position(0.0), np.zeros(3)) == pytest.approx(
        nominal.done_time
    )
    assert st == guide.initial_state()  # the state is not modified
    for i in np.linspace(0, len(nominal.t) - 2, 9).astype(int).tolist():
        st, x, v_ref, v = nominal.guide_state(i), nominal.x[i], nominal.v_ref[i], nominal.v[i]
        ref = reference_etc(guide, adm, st, x, v_ref, v)
        assert ref == pytest.approx(nominal.done_time - nominal.t[i], abs=1e-9)


def test_reference_brake_done_and_horizon(guide: Guide, adm: VariableAdmittance) -> None:
    n = guide.n_legs
    done = GuideState(EX.length, n, True)
    end = EX.position(EX.length)
    assert reference_etc(guide, adm, done, end, np.zeros(3)) == 0.0
    # after the last leg the hand brakes at max_acceleration
    moving = np.array([0.1, 0.0, 0.0])
    assert reference_etc(guide, adm, done, end, np.zeros(3), moving) == pytest.approx(
        0.1 / P.max_acceleration, abs=0.0021
    )
    short = reference_etc(
        guide, adm, guide.initial_state(), EX.position(0.0), np.zeros(3), t_max=1.0
    )
    assert math.isinf(short)


def test_fast_etc_nominal_and_done(fast: FastETC, nominal: VirtualRun) -> None:
    assert nominal.done_time is not None
    assert fast.nominal() == pytest.approx(nominal.done_time, rel=0.02)
    done = GuideState(EX.length, fast.guide.n_legs, True)
    end = EX.position(EX.length)
    assert fast.etc(done, end, np.zeros(3)) == 0.0
    braking = np.array([0.0, 0.07, 0.0])
    assert fast.etc(done, end, np.zeros(3), braking) == pytest.approx(0.07 / P.max_acceleration)


def test_fast_etc_along_the_nominal_run(fast: FastETC, nominal: VirtualRun) -> None:
    assert nominal.done_time is not None
    idx = np.arange(0, len(nominal.t) - 1, 25)
    est = np.array(
        [
            fast.etc(nominal.guide_state(i), nominal.x[i], nominal.v_ref[i], nominal.v[i])
            for i in idx.tolist()
        ]
    )
    ref = nominal.done_time - nominal.t[idx]
    err = np.abs(est - ref)
    assert np.max(err / np.maximum(ref, 0.1)) <= 0.02
    assert np.max(err) < 0.15


def test_fast_etc_agrees_with_reference_off_nominal() -> None:
    """Random paces and resisting users (states slowed, pushed back, lagging the admittance)."""
    res = etc_agreement(EX, P, np.random.default_rng(7), n_runs=4, samples_per_run=8)
    assert res["n_states"] >= 30
    assert res["max_rel_err"] <= 0.02
    assert res["mean_rel_err"] <= 0.01


def test_fast_etc_with_exact_tracking() -> None:
    """Without the acceleration limit the law reduces to the admittance's exponential."""
    params = AdmittanceParams(max_acceleration=math.inf)
    res = etc_agreement(EX, params, np.random.default_rng(11), n_runs=3, samples_per_run=8)
    assert res["max_abs_err"] <= 0.05
    assert res["max_rel_err"] <= 0.02 + 0.002 / 0.1  # one tick in the last 0.1 s
    assert res["mean_rel_err"] <= 0.01


def test_fast_etc_on_another_geometry() -> None:
    """Two straight legs at a right angle: the tables are not exercise-specific."""
    tr = Trajectory(
        [
            LineSegment(np.zeros(3), np.array([0.4, 0.0, 0.0]), waypoint=True),
            LineSegment(np.array([0.4, 0.0, 0.0]), np.array([0.4, 0.3, 0.0]), waypoint=True),
        ]
    )
    g = Guide(tr, P)
    a = VariableAdmittance(P)
    f = FastETC(g, a)
    run = simulate_virtual(
        tr,
        P,
        p=random_pace(np.random.default_rng(3)),
        force=random_resistance(np.random.default_rng(4), horizon=8.0),
    )
    assert run.done_time is not None
    for i in np.linspace(0, len(run.t) - 2, 12).astype(int).tolist():
        st, x, v_ref, v = run.guide_state(i), run.x[i], run.v_ref[i], run.v[i]
        ref = reference_etc(g, a, st, x, v_ref, v)
        assert abs(f.etc(st, x, v_ref, v) - ref) <= 0.03 * max(ref, 0.1)


def test_simulate_virtual_records_inputs() -> None:
    run = simulate_virtual(EX, P, p=0.8, force=lambda t, v, b: -3.0 * b, t_max=2.0)
    assert run.done_time is None
    n = len(run.t)
    assert run.x.shape == (n, 3) and run.v.shape == (n, 3) and run.f_ext.shape == (n, 3)
    assert run.v_ref.shape == (n, 3)
    assert np.all(run.p == 0.8)
    np.testing.assert_allclose(np.linalg.norm(run.f_ext[1:], axis=1), 3.0)
    # slower pace and resistance: slower than the nominal plateau
    assert run.max_speed < 0.8 * (10.0 - 3.0) / 80.0 + 1e-3
    # the command never changes faster than max_acceleration
    dv = np.linalg.norm(np.diff(run.v, axis=0), axis=1)
    assert dv.max() <= P.max_acceleration * 0.002 + 1e-12


def test_fast_etc_validation(guide: Guide, adm: VariableAdmittance) -> None:
    with pytest.raises(ConfigError, match="propel_force"):
        FastETC(Guide(line([0, 0, 0], [1, 0, 0]), AdmittanceParams(propel_force=0.0)), adm)
    with pytest.raises(ConfigError, match="dt"):
        FastETC(guide, adm, dt=0.0)
    with pytest.raises(ConfigError, match="u_range"):
        FastETC(guide, adm, u_range=(0.1, 0.3))
    with pytest.raises(ConfigError, match="dt"):
        simulate_virtual(EX, P, dt=-1.0)


@settings(deadline=None, max_examples=300)
@given(
    st.floats(-0.6, 0.6),
    st.floats(-0.6, 0.6),
    st.floats(0.01, 0.5),
    st.floats(0.05, 2.0),
    st.sampled_from([0.0, 1e-13, -1e-13]),
)
def test_ramp_end_two_halvings_a_round_is_the_plain_bisection(
    u0: float, w0: float, ui: float, tau: float, nudge: float
) -> None:
    """The compiled ramp end (two halvings per round, evaluated side by side) returns the plain
    bisection's bracket end to the bit, the near-equal ``u0 = w0`` branch included."""
    from langenv.control import motion_etc_kernels as ek

    prm = ek.ETC_PARAMS.zeros()
    prm[ek.ETC_PARAMS.at.u_inf], prm[ek.ETC_PARAMS.at.tau], prm[ek.ETC_PARAMS.at.acc] = (
        ui,
        tau,
        0.14,
    )
    for w in (w0, u0 + nudge):
        assert ek.ramp_end(prm, u0, w) == motion_etc.ramp_end(prm, u0, w)


def test_ramp_end_stops_after_sixty_halvings_like_the_plain_bisection() -> None:
    """A bracket that never gets under 1 us (a huge one) ends after 60 halvings either way."""
    from langenv.control import motion_etc_kernels as ek

    prm = ek.ETC_PARAMS.zeros()
    prm[ek.ETC_PARAMS.at.u_inf], prm[ek.ETC_PARAMS.at.tau], prm[ek.ETC_PARAMS.at.acc] = (
        1e9,
        0.5,
        1e-12,
    )
    assert ek.ramp_end(prm, 0.0, 1.0) == motion_etc.ramp_end(prm, 0.0, 1.0)
