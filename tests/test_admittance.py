"""The variable admittance A(p): validation, exactness, time-warp property, passivity."""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from langenv.control.admittance import AdmittanceParams, VariableAdmittance
from langenv.control.guide import Guide, GuideState
from langenv.control.trajectory import line
from langenv.errors import ConfigError

P = AdmittanceParams()
M0, D0, K, FP = P.mass, P.damping, P.stiffness, P.propel_force


# ------------------------------------------------------------------------------ validation
@pytest.mark.parametrize(
    ("field", "value"),
    [
        ("mass", 0.0),
        ("mass", -1.0),
        ("damping", 0.0),
        ("stiffness", -5.0),
        ("propel_force", -0.1),
        ("switch_tol", 0.0),
        ("switch_tol", -1.0),
        ("max_acceleration", 0.0),
        ("max_acceleration", -math.inf),
        ("max_acceleration", math.nan),
        ("mass", math.nan),
        ("damping", math.inf),
        ("mass", True),
    ],
)
def test_params_validation_names_the_field(field: str, value: float) -> None:
    with pytest.raises(ConfigError, match=field):
        AdmittanceParams(**{field: value})  # type: ignore[arg-type]


def test_params_defaults_and_plateau() -> None:
    assert (P.mass, P.damping, P.stiffness, P.propel_force) == (40.0, 80.0, 120.0, 10.0)
    assert P.plateau_speed == pytest.approx(0.125)
    assert not hasattr(P, "p_max")  # the pace bounds' one source is PaceLimits
    with pytest.raises(ConfigError, match="curvature_feedforward"):
        AdmittanceParams(curvature_feedforward="yes")  # type: ignore[arg-type]


@pytest.mark.parametrize(
    ("kwargs", "name"),
    [
        ({"p": 0.0}, "p"),
        ({"p": -0.5}, "p"),
        ({"p": math.inf}, "p"),
        ({"p": math.nan}, "p"),
        ({"force": np.array([math.nan, 0, 0])}, "force"),
        ({"force": np.array([0, math.inf, 0])}, "force"),
        ({"v": np.array([0, 0, math.nan])}, "v"),
        ({"dt": 0.0}, "dt"),
        ({"dt": -0.002}, "dt"),
        ({"p_dot": math.nan}, "p_dot"),
        ({"p_dot": -1000.0}, "p_dot"),
    ],
)
def test_step_validation_names_the_argument(kwargs: dict[str, object], name: str) -> None:
    adm = VariableAdmittance(P)
    args: dict[str, object] = {
        "v": np.zeros(3),
        "force": np.ones(3),
        "p": 1.0,
        "p_dot": 0.0,
        "dt": 0.002,
    }
    args.update(kwargs)
    with pytest.raises(ConfigError, match=rf"\b{name}\b"):
        adm.step(**args)  # type: ignore[arg-type]


def test_any_positive_pace_is_accepted() -> None:
    """The admittance works for any pace > 0; the env's PaceLimits bound it, not the admittance."""
    adm = VariableAdmittance(P)
    for p in (0.3, 1.6, 2.5):
        v = adm.step(np.zeros(3), np.array([10.0, 0.0, 0.0]), p, 0.0, 0.002)
        assert np.all(np.isfinite(v)) and v[0] > 0.0


def test_constructor_rejects_wrong_params() -> None:
    with pytest.raises(ConfigError, match="params"):
        VariableAdmittance({"mass": 40.0})  # type: ignore[arg-type]


# ------------------------------------------------------------------------------ exactness
@pytest.mark.parametrize("dt", [0.002, 0.05, 1.0])
def test_p1_constant_force_is_exact_at_any_step(dt: float) -> None:
    """With p = 1 the step is the exact solution of M0 dv/dt + D0 v = F (stable at any dt)."""
    adm = VariableAdmittance(P)
    f = np.array([10.0, -4.0, 2.0])
    v0 = np.array([0.3, 0.1, -0.2])
    v = v0.copy()
    n = round(2.0 / dt)
    for _ in range(n):
        v = adm.step(v, f, 1.0, 0.0, dt)
    t = n * dt
    exact = f / D0 + (v0 - f / D0) * math.exp(-D0 / M0 * t)
    np.testing.assert_allclose(v, exact, rtol=1e-10, atol=1e-13)


def test_constant_pace_scales_force_and_damping() -> None:
    """With constant p: M0 dv/dt = p^2 F - p D0 v, so v settles at p F / D0."""
    adm = VariableAdmittance(P)
    f = np.array([8.0, 0.0, 0.0])
    v = np.zeros(3)
    for _ in range(5000):
        v = adm.step(v, f, 1.3, 0.0, 0.002)
    np.testing.assert_allclose(v, 1.3 * f / D0, rtol=1e-9)


def test_step_returns_a_new_array() -> None:
    adm = VariableAdmittance(P)
    v = np.zeros(3)
    out = adm.step(v, np.ones(3), 1.0, 0.0, 0.002)
    assert out is not v and out.shape == (3,) and np.all(v == 0.0)


# ------------------------------------------------------------------------------ time warp
class _SmoothPace:
    """p(t) = 1 + a sum of sinusoids, scaled into [0.61, 1.39], with its exact integral."""

    def __init__(self, amps: list[float], freqs: list[float], phases: list[float]) -> None:
        total = sum(abs(a) for a in amps)
        scale = 0.39 / total if total > 0.39 else 1.0
        self.terms = [
            (scale * a, 2 * math.pi * f, ph) for a, f, ph in zip(amps, freqs, phases, strict=True)
        ]

    def __call__(self, t: float) -> float:
        return 1.0 + sum(a * math.sin(w * t + ph) for a, w, ph in self.terms)

    def phi(self, t: float) -> float:
        """Integral of p from 0 to t."""
        return t + sum(a * (math.cos(ph) - math.cos(w * t + ph)) / w for a, w, ph in self.terms)


def _smooth_pace(amps: list[float], freqs: list[float], phases: list[float]) -> _SmoothPace:
    return _SmoothPace(amps, freqs, phases)


def _warp_error(
    p: _SmoothPace, f: np.ndarray, v_star0: np.ndarray, dt: float, t_end: float = 2.0
) -> float:
    adm = VariableAdmittance(P)
    v = p(0.0) * v_star0
    n = round(t_end / dt)
    err = 0.0
    for k in range(n):
        t = k * dt
        p_k, p_next = p(t), p(t + dt)
        v = adm.step(v, f, p_k, (p_next - p_k) / dt, dt)
        if (k + 1) % round(0.25 / dt) == 0:
            t1 = (k + 1) * dt
            phi = p.phi(t1)
            v_star = f / D0 + (v_star0 - f / D0) * math.exp(-D0 / M0 * phi)
            err = max(err, float(np.linalg.norm(v - p(t1) * v_star)))
    return err


@settings(max_examples=25, deadline=None)
@given(
    amps=st.lists(st.floats(-0.4, 0.4), min_size=1, max_size=3),
    freqs=st.lists(st.floats(0.1, 2.0), min_size=3, max_size=3),
    phases=st.lists(st.floats(0.0, 6.3), min_size=3, max_size=3),
    force=st.tuples(*[st.floats(-30.0, 30.0)] * 3),
    v0=st.tuples(*[st.floats(-0.3, 0.3)] * 3),
)
def test_time_warp_property(
    amps: list[float],
    freqs: list[float],
    phases: list[float],
    force: tuple[float, float, float],
    v0: tuple[float, float, float],
) -> None:
    """For a fixed force, v(t) = p(t) v*(Phi(t)), Phi = integral of p (SPEC §1)."""
    p = _smooth_pace(amps, freqs[: len(amps)], phases[: len(amps)])
    f = np.array(force)
    v_star0 = np.array(v0)
    scale = 1e-3 + float(np.linalg.norm(f)) / D0 + float(np.linalg.norm(v_star0))
    e_coarse = _warp_error(p, f, v_star0, 0.004)
    e_fine = _warp_error(p, f, v_star0, 0.002)
    assert e_fine <= 1e-4 * scale
    # the error is a discretisation error: it shrinks with dt (second order here)
    assert e_fine <= 0.5 * e_coarse + 1e-12 * scale


def test_time_warp_fails_without_the_pdot_term() -> None:
    """Sanity check that the property test can fail: drop p_dot and the warp breaks."""
    p = _smooth_pace([0.3], [0.5], [0.0])
    f = np.array([10.0, 0.0, 0.0])
    adm = VariableAdmittance(P)
    dt = 0.002
    v = p(0.0) * np.zeros(3)
    for k in range(1000):
        v = adm.step(v, f, p(k * dt), 0.0, dt)
    phi = p.phi(2.0)
    v_star = f / D0 * (1.0 - math.exp(-D0 / M0 * phi))
    assert np.linalg.norm(v - p(2.0) * v_star) > 1e-3


# ------------------------------------------------------------------------------ passivity
def _passivity_run(
    p: Callable[[float], float],
    forces: list[tuple[float, float, float]],
    dt: float,
    t_end: float = 2.0,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Virtual loop on a straight line (no stop within reach), x integrated from v_ref.

    Returns V(t) - V(0), the supplied energy W(t) = int F_ext . v dt and the dissipation
    int p^-1 v^T D0 v dt, at every tick.
    """
    traj = line([-10.0, 0.0, 0.0], [10.0, 0.0, 0.0])
    guide = Guide(traj, P)
    adm = VariableAdmittance(P)
    u = traj.tangent(0.0)
    state = GuideState(s=10.0, leg=0, done=False)
    x = traj.position(10.0) + np.array([0.0, 0.02, -0.01])
    v = np.array([0.05, -0.02, 0.0])
    seg = 0.25  # the force changes every 0.25 s

    def storage(x: np.ndarray, v: np.ndarray, pk: float) -> float:
        x_par = float((x - traj.position(0.0)) @ u)
        x_perp = x - traj.position(0.0) - x_par * u
        return 0.5 * K * float(x_perp @ x_perp) - FP * x_par + 0.5 * M0 * float(v @ v) / pk**2

    n = round(t_end / dt)
    v_hist = [storage(x, v, p(0.0))]
    w_hist, d_hist = [0.0], [0.0]
    for k in range(n):
        t = k * dt
        f_ext = np.array(forces[min(int(t / seg), len(forces) - 1)])
        guide.update(state, x)
        pk, pn = p(t), p(t + dt)
        v_new = adm.step(v, guide.virtual_force(state, x, v, pk) + f_ext, pk, (pn - pk) / dt, dt)
        x = x + v_new * dt
        w_hist.append(w_hist[-1] + float(f_ext @ (v + v_new)) * 0.5 * dt)
        d_hist.append(d_hist[-1] + 0.5 * dt * D0 * (float(v @ v) / pk + float(v_new @ v_new) / pn))
        v = v_new
        v_hist.append(storage(x, v, pn))
    return np.array(v_hist) - v_hist[0], np.array(w_hist), np.array(d_hist)


@settings(max_examples=15, deadline=None)
@given(
    amps=st.lists(st.floats(-0.4, 0.4), min_size=2, max_size=2),
    freqs=st.lists(st.floats(0.1, 2.0), min_size=2, max_size=2),
    forces=st.lists(st.tuples(*[st.floats(-25.0, 25.0)] * 3), min_size=8, max_size=8),
)
def test_passivity_on_a_straight_line(
    amps: list[float], freqs: list[float], forces: list[tuple[float, float, float]]
) -> None:
    """V(t) - V(0) <= int F_ext^T v dt (paper Theorem 1), and dV/dt = F_ext^T v - v^T D0 v / p."""
    p = _smooth_pace(amps, freqs, [0.3, 1.1])
    excess, resid = [], []
    for dt in (0.004, 0.002):
        dv, w, d = _passivity_run(p, forces, dt)
        excess.append(float(np.max(dv - w)))
        resid.append(float(np.max(np.abs(dv - (w - d)))))
    scale = 1.0 + float(np.max(np.abs(w))) + float(np.max(d))
    # passivity: the storage never grows beyond the energy supplied, up to an O(dt) tolerance
    for dt, ex in zip((0.004, 0.002), excess, strict=True):
        assert ex <= 0.25 * dt * scale
    # the energy balance holds up to a discretisation error, O(dt): it halves with dt
    assert resid[1] <= 0.6 * resid[0] + 1e-12
    assert resid[1] <= 0.5 * 0.002 * scale


def test_passivity_dissipates_without_external_force() -> None:
    """With F_ext = 0 the storage function decreases (D0 > 0, p > 0)."""
    p = _smooth_pace([0.35], [0.7], [0.0])
    dv, w, _ = _passivity_run(p, [(0.0, 0.0, 0.0)], 0.002)
    assert np.all(w == 0.0)
    assert dv[-1] < -0.01
    assert np.max(np.diff(dv)) < 1e-5
