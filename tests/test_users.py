"""Simulated users (langenv.users): protocol, callable, replay and synthetic."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from langenv.control.cooperation import CooperationFilter
from langenv.errors import ConfigError
from langenv.robot.force_sensor import ForceSensor
from langenv.users import (
    CallableUser,
    LogNormal,
    ReplayUser,
    Session,
    SyntheticUser,
    SyntheticUserParams,
    User,
    against_motion,
    invert_cooperation,
    load_sessions,
)
from langenv.users.synthetic import CALIBRATED_YAML, Episode, ar1_filter

CALIBRATED_PARAMS = SyntheticUserParams.calibrated()

SESSIONS = Path(__file__).parents[2] / "shared" / "sessions"
DT = 0.002
TANGENT = np.array([0.6, -0.8, 0.0])


def _sessions() -> list[Session]:
    if not SESSIONS.is_dir():
        pytest.skip(f"recorded sessions not found at {SESSIONS}")
    return load_sessions(SESSIONS)


def _replay_cooperation(user: User, end: float, tangent: np.ndarray = TANGENT) -> np.ndarray:
    """Run a user through the sensor (deadband) and cooperation filter at 500 Hz.

    Returns c after each tick: ``out[k]`` is the cooperation at time ``(k + 1) * DT``.
    """
    sensor = ForceSensor(noise_std=0.0, deadband=5.0)
    coop = CooperationFilter(alpha=0.1, f_max=15.0)
    n = math.ceil(end / DT)
    out = np.empty(n)
    v = np.zeros(3)
    for k in range(n):
        out[k] = coop.update(sensor.magnitude(user.force(k * DT, v, tangent), None), DT)
    return out


def _rmse_against(session: Session, c_ticks: np.ndarray) -> float:
    times = (np.arange(c_ticks.size) + 1) * DT
    c_sim = np.interp(session.t, np.concatenate([[0.0], times]), np.concatenate([[1.0], c_ticks]))
    return float(np.sqrt(np.mean((c_sim - session.cooperation) ** 2)))


# --------------------------------------------------------------------------------------------
# base: protocol, direction, CallableUser
# --------------------------------------------------------------------------------------------


@settings(max_examples=50, deadline=None)
@given(
    magnitude=st.one_of(st.just(0.0), st.floats(1e-6, 100.0)),
    tangent=st.lists(st.floats(-10.0, 10.0), min_size=3, max_size=3).filter(
        lambda v: math.sqrt(sum(x * x for x in v)) > 1e-3
    ),
)
def test_against_motion_is_minus_tangent(magnitude: float, tangent: list[float]) -> None:
    b = np.array(tangent)
    f = against_motion(magnitude, b)
    assert f.shape == (3,)
    assert np.linalg.norm(f) == pytest.approx(magnitude, rel=1e-9, abs=1e-12)
    if magnitude > 0.0:
        np.testing.assert_allclose(f / magnitude, -b / np.linalg.norm(b), atol=1e-12)


def test_against_motion_rejects_bad_tangent() -> None:
    with pytest.raises(ConfigError, match="tangent"):
        against_motion(3.0, np.zeros(3))
    with pytest.raises(ConfigError, match="tangent"):
        against_motion(3.0, np.ones(2))


def test_callable_user_passes_valid_output_and_reset() -> None:
    seen: list[float] = []

    def push(t: float, v: np.ndarray, b: np.ndarray) -> list[float]:
        return [t, 0.0, -1.0]

    user = CallableUser(push, on_reset=lambda rng: seen.append(float(rng.random())))
    assert isinstance(user, User)
    np.testing.assert_array_equal(user.force(2.0, np.zeros(3), TANGENT), [2.0, 0.0, -1.0])
    user.reset(np.random.default_rng(3))
    assert seen == [np.random.default_rng(3).random()]


@pytest.mark.parametrize(
    ("output", "fragment"),
    [
        (np.zeros(2), "shape (2,)"),
        (np.zeros((3, 1)), "shape (3, 1)"),
        ([0.0, math.nan, 0.0], "non-finite"),
        ([0.0, math.inf, 0.0], "non-finite"),
        ("abc", "(3,) force"),
        (None, "shape ()"),
    ],
)
def test_callable_user_rejects_bad_output(output: object, fragment: str) -> None:
    def my_bad_user(t: float, v: np.ndarray, b: np.ndarray) -> object:
        return output

    user = CallableUser(my_bad_user)
    with pytest.raises(ConfigError) as info:
        user.force(0.0, np.zeros(3), TANGENT)
    assert "my_bad_user" in str(info.value)
    assert fragment in str(info.value)


def test_callable_user_rejects_non_callables() -> None:
    with pytest.raises(ConfigError, match="fn must be callable"):
        CallableUser(42)  # type: ignore[arg-type]
    with pytest.raises(ConfigError, match="on_reset"):
        CallableUser(lambda t, v, b: np.zeros(3), on_reset=1)  # type: ignore[arg-type]


# --------------------------------------------------------------------------------------------
# replay
# --------------------------------------------------------------------------------------------


def _known_force_session() -> tuple[Session, np.ndarray]:
    """A 50 Hz cooperation trace produced by a known post-deadband force profile."""
    t_fine = np.arange(0, 12.0, DT)
    f_tilde = 9.0 * np.exp(-(((t_fine - 3.0) / 0.8) ** 2)) + 4.0 * ((t_fine > 6) & (t_fine < 9))
    coop = CooperationFilter()
    c = np.array([coop.update(f, DT) for f in f_tilde])
    idx = np.arange(0, t_fine.size, 10)
    # c[k] is the value at time (k + 1) * DT
    session = Session(name="known", t=(idx + 1) * DT, cooperation=c[idx])
    return session, f_tilde


def test_replay_reproduces_a_known_trace_and_its_force() -> None:
    session, f_tilde = _known_force_session()
    user = ReplayUser(session)
    user.reset(np.random.default_rng(0))
    c = _replay_cooperation(user, session.t[-1])
    assert _rmse_against(session, c) < 0.01
    # The recovered force matches the one that produced the trace (away from the steps).
    grid_f = user.f_tilde[: f_tilde.size]
    smooth = slice(500, 2800)  # around the Gaussian bump
    np.testing.assert_allclose(grid_f[smooth], f_tilde[smooth], atol=0.5)
    # The person pushes deadband + |F~| whenever the sensor should see a force.
    pushing = user.f_tilde > 0
    np.testing.assert_allclose(user.f_applied[pushing], user.f_tilde[pushing] + 5.0)
    assert np.all(user.f_applied[~pushing] == 0.0)


def test_replay_force_direction_and_end() -> None:
    session, _ = _known_force_session()
    user = ReplayUser(session)
    t = 3.0
    f = user.force(t, np.array([0.1, 0.0, 0.0]), TANGENT)
    assert np.linalg.norm(f) > 5.0
    np.testing.assert_allclose(f / np.linalg.norm(f), -TANGENT, atol=1e-12)
    assert user.magnitude(t) == pytest.approx(float(user.magnitude_array(np.array([t]))[0]))
    # After the recording: full cooperation.
    np.testing.assert_array_equal(user.force(user.end_time + 0.01, np.zeros(3), TANGENT), 0.0)
    assert user.magnitude(1e6) == 0.0
    with pytest.raises(ConfigError, match="t must be >= 0"):
        user.magnitude(-1.0)


def test_replay_lead_in_reaches_first_sample() -> None:
    # Recording starts at 0.6 s with c already at 0.7: a constant force before it gets there.
    t = np.linspace(0.6, 4.0, 171)
    session = Session(name="late", t=t, cooperation=0.7 + 0.3 * (t - 0.6) / 3.4)
    user = ReplayUser(session)
    c = _replay_cooperation(user, t[-1])
    assert _rmse_against(session, c) < 0.02


def test_replay_validates_arguments(tmp_path: Path) -> None:
    session, _ = _known_force_session()
    with pytest.raises(ConfigError, match="deadband"):
        ReplayUser(session, deadband=-1.0)
    with pytest.raises(ConfigError, match="alpha"):
        ReplayUser(session, alpha=1.5)
    with pytest.raises(ConfigError, match="smoothing"):
        ReplayUser(session, smoothing=0.0)
    with pytest.raises(ConfigError, match="session"):
        ReplayUser("u1.csv")  # type: ignore[arg-type]
    with pytest.raises(ConfigError, match="f_max"):
        invert_cooperation(session.t, session.cooperation, f_max=0.0)


def test_replay_from_csv(tmp_path: Path) -> None:
    session, _ = _known_force_session()
    lines = ["t,cooperation"] + [
        f"{a:.6f},{b:.8f}" for a, b in zip(session.t, session.cooperation, strict=True)
    ]
    path = tmp_path / "lab_session.csv"
    path.write_text("\n".join(lines) + "\n")
    user = ReplayUser.from_csv(path)
    assert user.session.name == "lab_session"
    np.testing.assert_allclose(user.f_tilde, ReplayUser(session).f_tilde, atol=1e-3)


def test_replay_of_recorded_sessions_gives_back_their_cooperation() -> None:
    sessions = _sessions()
    errors = {}
    for s in sessions:
        c = _replay_cooperation(ReplayUser(s), s.t[-1])
        errors[s.name] = _rmse_against(s, c)
    worst = max(errors, key=errors.__getitem__)
    mean = float(np.mean(list(errors.values())))
    print(f"replay RMSE: worst {errors[worst]:.4f} ({worst}), mean {mean:.4f}")
    assert errors[worst] <= 0.05


# --------------------------------------------------------------------------------------------
# synthetic
# --------------------------------------------------------------------------------------------


def _forces(user: SyntheticUser, seed: int, times: np.ndarray) -> np.ndarray:
    user.reset(np.random.default_rng(seed))
    return np.array([user.force(float(t), np.zeros(3), TANGENT) for t in times])


def test_synthetic_same_seed_same_user_different_seed_differs() -> None:
    times = np.arange(0.0, 30.0, 0.01)
    a = _forces(SyntheticUser(), 7, times)
    b = _forces(SyntheticUser(), 7, times)
    c = _forces(SyntheticUser(), 8, times)
    np.testing.assert_array_equal(a, b)
    assert not np.array_equal(a, c)
    # Re-resetting one user with the seed gives the same forces again.
    user = SyntheticUser()
    first = _forces(user, 7, times)
    _forces(user, 99, times)
    np.testing.assert_array_equal(_forces(user, 7, times), first)
    assert np.any(np.linalg.norm(a, axis=1) > 5.0)  # it does resist


@settings(max_examples=25, deadline=None)
@given(
    seed=st.integers(0, 2**32 - 1),
    t=st.floats(0.0, 60.0),
    tangent=st.lists(st.floats(-1.0, 1.0), min_size=3, max_size=3).filter(
        lambda v: math.sqrt(sum(x * x for x in v)) > 1e-2
    ),
)
def test_synthetic_force_is_against_the_tangent(seed: int, t: float, tangent: list[float]) -> None:
    user = SyntheticUser()
    user.reset(np.random.default_rng(seed))
    b = np.array(tangent)
    f = user.force(t, np.zeros(3), b)
    magnitude = user.magnitude(t)
    assert magnitude == 0.0 or magnitude > CALIBRATED_PARAMS.deadband
    np.testing.assert_allclose(f, -magnitude * b / np.linalg.norm(b), atol=1e-9)


def test_synthetic_force_follows_the_drawn_episodes() -> None:
    params = SyntheticUserParams.calibrated(noise_std=0.0)
    user = SyntheticUser(params)
    user.reset(np.random.default_rng(5))
    assert user.episodes
    for ep in user.episodes:
        assert ep.rise + ep.fall <= ep.duration + 1e-12
        if ep.duration - ep.rise - ep.fall < 0.05 or ep.end > params.horizon:
            continue  # no plateau to probe between grid points, or cut by the horizon
        mid = ep.onset + ep.rise + 0.5 * (ep.duration - ep.rise - ep.fall)
        assert user.magnitude(mid) == pytest.approx(ep.magnitude + params.deadband, rel=1e-6)
    gaps = [b.onset - a.end for a, b in zip(user.episodes, user.episodes[1:], strict=False)]
    assert all(g > 0 for g in gaps)
    between = 0.5 * (user.episodes[0].end + user.episodes[1].onset)
    assert user.magnitude(between) == 0.0


def test_episode_count_pmf_limits_episodes() -> None:
    params = SyntheticUserParams.calibrated(count_pmf=(0.0, 0.0, 1.0))
    for seed in range(5):
        user = SyntheticUser(params)
        user.reset(np.random.default_rng(seed))
        assert len(user.episodes) == 2
    none = SyntheticUser(SyntheticUserParams.calibrated(count_pmf=(1.0,)))
    none.reset(np.random.default_rng(0))
    assert not none.episodes
    assert np.all(none.f_applied == 0.0)


@settings(max_examples=30, deadline=None)
@given(
    onset=st.floats(0.0, 10.0),
    duration=st.floats(0.1, 5.0),
    rise_frac=st.floats(0.0, 0.5),
    fall_frac=st.floats(0.0, 0.5),
    magnitude=st.floats(0.1, 20.0),
)
def test_episode_envelope_is_a_bounded_trapezoid(
    onset: float, duration: float, rise_frac: float, fall_frac: float, magnitude: float
) -> None:
    ep = Episode(onset, duration, rise_frac * duration, fall_frac * duration, magnitude)
    t = np.linspace(onset - 1.0, ep.end + 1.0, 2001)
    env = ep.envelope(t)
    assert np.all(env >= 0.0)
    assert np.all(env <= magnitude * (1 + 1e-12))
    assert np.all(env[(t <= onset) | (t >= ep.end)] == 0.0)
    flat = (t >= onset + ep.rise) & (t <= ep.end - ep.fall) & (t > onset) & (t < ep.end)
    np.testing.assert_allclose(env[flat], magnitude)


@pytest.mark.parametrize(
    ("field", "value"),
    [
        ("p_start_resisting", 1.5),
        ("session_sigma", -0.1),
        ("noise_std", math.nan),
        ("noise_tau", 0.0),
        ("max_excess", -1.0),
        ("horizon", 0.0),
        ("resolution", 0.0),
        ("gap", 2.0),
        ("count_pmf", (0.5, 0.2)),
        ("count_pmf", (1.5, -0.5)),
    ],
)
def test_synthetic_params_are_validated(field: str, value: object) -> None:
    with pytest.raises(ConfigError, match=field):
        dataclasses.replace(CALIBRATED_PARAMS, **{field: value})  # type: ignore[arg-type]


def test_lognormal_validation_and_fit() -> None:
    with pytest.raises(ConfigError, match="median"):
        LogNormal(median=0.0, sigma=1.0)
    with pytest.raises(ConfigError, match="sigma"):
        LogNormal(median=1.0, sigma=-1.0)
    with pytest.raises(ConfigError, match="no field"):
        SyntheticUserParams.calibrated(speed=3.0)
    rng = np.random.default_rng(0)
    true = LogNormal(median=2.0, sigma=0.6)
    x = np.array([true.sample(rng) for _ in range(4000)])
    fit = LogNormal.fit(x)
    assert fit.median == pytest.approx(2.0, rel=0.05)
    assert fit.sigma == pytest.approx(0.6, rel=0.05)
    # Right-censoring at 2.5: the censored fit recovers the truth, the naive one does not.
    cut = x > 2.5
    observed = np.minimum(x, 2.5)
    censored = LogNormal.fit(observed, censored=cut)
    naive = LogNormal.fit(observed)
    assert censored.median == pytest.approx(2.0, rel=0.06)
    assert censored.sigma == pytest.approx(0.6, rel=0.08)
    assert abs(naive.sigma - 0.6) > 3 * abs(censored.sigma - 0.6)


# --------------------------------------------------------------------------------------------
# the calibrated parameters: stored as YAML
# --------------------------------------------------------------------------------------------


def test_calibrated_params_load_from_the_shipped_yaml() -> None:
    assert SyntheticUserParams.load(CALIBRATED_YAML) == CALIBRATED_PARAMS
    tweaked = SyntheticUserParams.calibrated(noise_std=0.1)
    assert tweaked.noise_std == 0.1 and tweaked.magnitude == CALIBRATED_PARAMS.magnitude
    with pytest.raises(ConfigError, match="no field"):
        SyntheticUserParams.calibrated(loudness=3.0)


def test_params_yaml_round_trip_and_errors(tmp_path: Path) -> None:
    import yaml

    path = tmp_path / "users.yaml"
    path.write_text(yaml.safe_dump({"params": CALIBRATED_PARAMS.to_dict()}))
    assert SyntheticUserParams.load(path) == CALIBRATED_PARAMS
    bad = CALIBRATED_PARAMS.to_dict()
    bad["magnitude"] = {"median": -1.0, "sigma": 0.2}
    path.write_text(yaml.safe_dump({"params": bad}))
    with pytest.raises(ConfigError, match=r"users\.yaml.*median"):
        SyntheticUserParams.load(path)
    bad = dict(CALIBRATED_PARAMS.to_dict(), loudness=1.0)
    path.write_text(yaml.safe_dump({"params": bad}))
    with pytest.raises(ConfigError, match=r"users\.yaml.*loudness"):
        SyntheticUserParams.load(path)
    path.write_text("params: [1, 2")
    with pytest.raises(ConfigError, match=r"users\.yaml"):
        SyntheticUserParams.load(path)
    with pytest.raises(ConfigError, match="nowhere"):
        SyntheticUserParams.load(tmp_path / "nowhere.yaml")


def test_synthetic_episode_counts_follow_the_pmf() -> None:
    pmf = np.asarray(CALIBRATED_PARAMS.count_pmf)
    rng = np.random.default_rng(123)
    n = 3000
    drawn = np.zeros(pmf.size)
    user = SyntheticUser()
    for _ in range(n):
        user.reset(rng)
        drawn[len(user.episodes)] += 1
    # Binomial standard error of each frequency, 4 sigma.
    tol = 4.0 * np.sqrt(pmf * (1.0 - pmf) / n) + 1e-12
    assert np.all(np.abs(drawn / n - pmf) <= tol), (drawn / n, pmf)


def test_synthetic_onsets_spread_like_the_recorded_ones() -> None:
    from eval.calibrate import extract_episodes

    sessions = _sessions()
    recorded = [extract_episodes(s) for s in sessions]
    rec_last = np.array([eps[-1].onset for eps in recorded if eps])
    rec_total = np.array([sum(e.duration for e in eps) for eps in recorded])
    rng = np.random.default_rng(77)
    syn_last, syn_total = [], []
    for _ in range(1000):
        user = SyntheticUser()
        user.reset(rng)
        syn_last.append(user.episodes[-1].onset)
        syn_total.append(sum(e.duration for e in user.episodes))
        assert all(e.onset < 60.0 for e in user.episodes)
    # Episodes start within the first seconds of the session as recorded (median of the last
    # onset within 3 s, 90th percentile within 6 s), and the resisting time per session is
    # of the recorded size (median within 35 %).
    assert abs(np.median(syn_last) - np.median(rec_last)) < 3.0
    assert abs(np.quantile(syn_last, 0.9) - np.quantile(rec_last, 0.9)) < 6.0
    assert abs(np.median(syn_total) / np.median(rec_total) - 1.0) < 0.35


def test_replay_grid_is_bounded() -> None:
    """invert_cooperation refuses a grid it cannot afford before allocating it."""
    from langenv.users.replay import invert_cooperation

    with pytest.raises(ConfigError, match="grid points"):
        invert_cooperation(np.array([0.0, 1e7]), np.array([1.0, 0.5]))
    with pytest.raises(ConfigError, match="grid points"):
        invert_cooperation(np.array([0.0, 10.0]), np.array([1.0, 0.5]), dt=1e-9)


@settings(deadline=None)  # the first example imports scipy.signal
@given(
    st.lists(st.floats(-1e6, 1e6), min_size=1, max_size=200),
    st.floats(0.0, 0.9999),
)
def test_ar1_filter_is_scipys_lfilter_to_the_bit(x: list[float], a: float) -> None:
    """The OU noise's filter gives scipy.signal.lfilter's samples exactly (episodes unchanged)."""
    from scipy.signal import lfilter

    arr = np.array(x)
    np.testing.assert_array_equal(ar1_filter(arr, a), lfilter([1.0], [1.0, -a], arr))


@pytest.mark.parametrize("seed", range(6))
def test_force_table_is_the_formula_over_the_whole_grid(seed: int) -> None:
    """``reset`` takes the noise's exp only where the person pushes; the table is the formula's,
    every sample computed, to the bit (0 wherever the envelope is)."""
    user = SyntheticUser()
    user.reset(np.random.default_rng(seed))
    p = user.params
    rng = np.random.default_rng(seed)
    user._draw_episodes(rng)  # the same draws, in the same order, as reset's
    envelope = np.zeros_like(user.grid)
    for ep in user.episodes:
        lo = int(np.searchsorted(user.grid, ep.onset, side="right"))
        hi = int(np.searchsorted(user.grid, ep.end, side="left"))
        if hi > lo:
            envelope[lo:hi] = ep.envelope(user.grid[lo:hi])
    noise = user._ou_noise(rng, user.grid.shape[0])
    bias = 0.5 * p.noise_std**2
    factor = np.array([math.exp(p.noise_std * z - bias) for z in noise.tolist()])
    expected = np.where(envelope > 0.0, np.minimum(envelope * factor, p.max_excess) + p.deadband, 0)
    assert user.f_applied.tobytes() == expected.tobytes()
    assert np.count_nonzero(envelope) > 0
