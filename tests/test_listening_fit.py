"""The jobs' listening people (``--users listening:N``, ``--listening``) and the fit of
``follow`` to the AC sessions (``eval.listening``)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from eval.listening import LAGS, Trace, fit_follow, lead_statistic, trace_from_session
from eval.users import parse_users
from langctrl.jobs.compare import main as compare_main
from langctrl.jobs.fidelity import main as fidelity_main
from langenv.users import ListeningParams, ListeningUser

SESSIONS = Path(__file__).parents[2] / "shared" / "sessions"


def test_users_name_synthetic_or_listening_people() -> None:
    syn = parse_users("synthetic:3")
    assert (syn.kind, syn.count, syn.model()) == ("synthetic", 3, None)
    assert syn.names(10) == [("s10", 10), ("s11", 11), ("s12", 12)]
    lis = parse_users("listening:2", "latency=1.5")
    person = lis.model()
    assert isinstance(person, ListeningUser) and person.listening.latency == 1.5
    assert lis.names(10) == syn.names(10)[:2]  # the same people
    assert parse_users("listening:2").listening == ListeningParams()
    for text, listening, message in [
        ("synthetic:0", None, "synthetic:N or listening:N with N >= 1"),
        ("hearing:3", None, "synthetic:N or listening:N"),
        ("listening:x", None, "got 'listening:x'"),
        ("synthetic:3", "latency=1", "give --users listening:3"),
        ("listening:3", "speed=1", "unknown key 'speed'"),
        ("listening:20000", None, "at most 10000"),
    ]:
        with pytest.raises(ValueError, match=message):
            parse_users(text, listening)


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--users", "listening:zero"], "listening:N"),
        (["--users", "synthetic:2", "--listening", "comply=0.5"], "give --users listening:2"),
        (["--users", "listening:2", "--listening", "comply=2"], "comply must lie in [0, 1]"),
    ],
)
def test_compare_refuses_bad_listening_arguments(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], args: list[str], message: str
) -> None:
    try:
        status = compare_main([*args, "--out", str(tmp_path / "out")])
    except SystemExit as exc:  # --users: the parser's own check
        status = int(exc.code or 0)
    assert status == 2
    assert message in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == []


def test_fidelity_refuses_listening_without_listening_people(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    args = ["--sessions", str(tmp_path), "--listening", "latency=1", "--out", str(tmp_path / "o")]
    assert fidelity_main(args) == 2
    assert "give --users listening:N" in capsys.readouterr().err


def test_compare_runs_listening_people(tmp_path: Path) -> None:
    out = tmp_path / "out"
    args = ["--policies", "lc", "--users", "listening:1", "--listening", "comply=1,nonresponders=0"]
    args += ["--decision-hz", "25", "--no-audio", "--no-figures", "--workers", "1"]
    assert compare_main([*args, "--out", str(out)]) == 0
    assert '"listening": "comply=1,nonresponders=0"' in (out / "config.json").read_text()


# --------------------------------------------------------------------------- the statistic
def _trace(beta: float, seed: int, trend: float = 0.0, tau: float = 1.0) -> Trace:
    """A session whose cooperation follows the lead ``tau`` s later with gain ``beta``, both
    confounded by a common quadratic trend of size ``trend``."""
    rng = np.random.default_rng(seed)
    dt, n = 0.02, 700
    t = np.arange(n) * dt
    k = round(tau / dt)
    lead = np.zeros(n)
    noise = np.zeros(n)
    for i in range(1, n):  # slow random walks: the lead and the person's own state
        lead[i] = 0.98 * lead[i - 1] + 0.2 * rng.standard_normal()
        noise[i] = 0.9 * noise[i - 1] + 0.1 * rng.standard_normal()
    drift = trend * (t / t[-1]) ** 2
    c = noise + drift
    c[k:] += beta * lead[:-k]
    lead = lead + drift
    return Trace("x", t, c, c.copy(), lead, np.ones(n, dtype=bool), float(t[-1]))


def test_the_lagged_statistic_finds_a_following_person_and_not_a_trend() -> None:
    follows = [lead_statistic(_trace(0.3, s), 1.0, "c") for s in range(8)]
    assert min(follows) > 0.2
    trend_only = [lead_statistic(_trace(0.0, s, trend=3.0), 1.0, "c") for s in range(8)]
    raw = [np.corrcoef(tr.lead, tr.c)[0, 1] for tr in (_trace(0.0, s, trend=3.0) for s in range(8))]
    assert np.median(raw) > 0.5  # the trend alone correlates them
    assert abs(float(np.mean(trend_only))) < 0.1  # held fixed, nothing is left
    short = Trace("y", np.arange(10) * 0.02, *(np.zeros(10),) * 3, np.ones(10, bool), 0.2)
    assert np.isnan(lead_statistic(short, 1.0, "c"))


@settings(max_examples=40, deadline=None)
@given(
    slope=st.floats(0.05, 1.0) | st.floats(-1.0, -0.05),
    follow=st.floats(-2.5, 2.5),
    offset=st.floats(-0.5, 0.5),
)
def test_the_fit_recovers_the_follow_that_made_the_statistics(
    slope: float, follow: float, offset: float
) -> None:
    grid = (-3.0, -1.0, 0.0, 1.0, 3.0)
    sims = np.array([[[offset + slope * g + 0.01 * j for j in range(len(LAGS))]] * 2 for g in grid])
    recorded = sims[0] + slope * (follow - grid[0])
    fit, fine, loss = fit_follow(recorded, np.ones_like(recorded), grid, sims)
    assert abs(fit - follow) <= (fine[1] - fine[0]) / 2 + 1e-9
    step = fine[1] - fine[0]
    assert loss.shape == fine.shape and loss.min() <= recorded.size * (slope * step) ** 2


def test_a_recorded_ac_session_gives_its_lead() -> None:
    if not SESSIONS.is_dir():
        pytest.skip(f"recorded sessions not found at {SESSIONS}")
    from langenv.users import load_session

    tr = trace_from_session(load_session(SESSIONS / "u3_ac.csv"))
    assert abs(tr.lead[1]) < 0.5  # speech and motion start together
    assert 12.0 < tr.t[tr.speaking][-1] < 14.5  # the speech runs its own 13.3 s
    assert tr.lead[tr.t.searchsorted(10.0)] > 3.0  # u3 resisted: the speech ran ahead
    assert tr.length == pytest.approx(21.93, abs=0.01)


# --------------------------------------------------------------------------- sweeps
def test_a_sweep_runs_listening_people_with_their_parameters(tmp_path: Path) -> None:
    import pickle

    from eval.sweep import SweepError, load_spec
    from eval.sweep.grid import expand

    path = tmp_path / "s.yaml"
    path.write_text(
        "grid: {policy: [lc]}\n"
        "users:\n"
        "  - {synthetic: 2}\n"
        "  - {listening: 2}\n"
        "  - {listening: 2, params: {latency: 1.5, comply: 0.3}}\n"
    )
    spec = load_spec(path)
    names = [u.name for u in spec.users]
    assert names == ["synthetic:2@0", "listening:2@0", "listening:2@0[latency=1.5,comply=0.3]"]
    assert spec.users[0].listening is None
    assert spec.users[2].listening == ListeningParams(latency=1.5, comply=0.3)
    jobs = [s.job for s in expand(spec)]
    assert [j.user_model is None for j in jobs] == [True, True, False, False, False, False]
    person = jobs[-1].user_model
    assert isinstance(person, ListeningUser) and person.listening.comply == 0.3
    copy = pickle.loads(pickle.dumps(person))  # a fresh person of the same parameters
    assert copy.listening == person.listening and len(pickle.dumps(person)) < 5000
    for bad, message in [
        ("{synthetic: 2, params: {latency: 1}}", "users.params (line 2): sets listening"),
        ("{listening: 2, params: {speed: 1}}", "unknown field(s) speed"),
        ("{listening: 2, params: {comply: 3}}", "comply must lie in [0, 1]"),
        ("{listening: 2, synthetic: 2}", "give exactly one of synthetic: N, listening: N"),
    ]:
        path.write_text(f"grid: {{policy: [lc]}}\nusers: {bad}\n")
        with pytest.raises(SweepError) as err:
            load_spec(path)
        assert message in str(err.value), str(err.value)
