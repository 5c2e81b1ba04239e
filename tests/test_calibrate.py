"""Calibration of the synthetic users (eval.calibrate): episodes, direct fit, stored parameters."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from eval.calibrate import (
    DURATION_SIGMA,
    MAGNITUDE_SIGMA,
    RATIO_CENTRE,
    STRUCTURE,
    ClosedLoopScore,
    extract_episodes,
    fit_params,
    round_params,
    structured,
    write_params,
)
from langctrl.jobs.calibrate import main
from langenv.errors import ConfigError
from langenv.users import Session, SyntheticUserParams, load_sessions

SESSIONS = Path(__file__).parents[2] / "shared" / "sessions"


def _sessions() -> list[Session]:
    if not SESSIONS.is_dir():
        pytest.skip(f"recorded sessions not found at {SESSIONS}")
    return load_sessions(SESSIONS)


def test_extract_episodes_finds_a_known_push() -> None:
    """A synthetic cooperation trace made by one 3 s push of 6 N above the deadband."""
    dt = 0.02
    t = np.arange(0.0, 12.0, dt)
    f = np.where((t > 2.0) & (t < 5.0), 6.0, 0.0)
    r = np.zeros_like(t)
    beta = 0.1**dt
    for k in range(1, t.size):
        r[k] = beta * r[k - 1] + (1.0 - beta) * min(f[k - 1], 15.0) / 15.0
    eps = extract_episodes(Session("push", t, 1.0 - r))
    assert len(eps) == 1
    ep = eps[0]
    assert ep.onset == pytest.approx(2.0, abs=0.1)
    assert ep.duration == pytest.approx(3.0, abs=0.2)
    assert ep.magnitude == pytest.approx(6.0, rel=0.1)
    assert not ep.left_censored and not ep.right_censored


def test_stored_calibration_is_the_procedure_s_result() -> None:
    """All but the closed-loop medians come from the direct fit and the session structure."""
    sessions = _sessions()
    direct, episodes = fit_params(sessions)
    assert len(episodes) >= 2 * len(sessions)
    stored = SyntheticUserParams.calibrated()
    rebuilt = round_params(structured(direct, stored.duration.median, stored.magnitude.median))
    assert rebuilt == stored
    for name, value in STRUCTURE.items():
        assert getattr(stored, name) == value
    assert stored.duration.sigma == DURATION_SIGMA
    assert stored.magnitude.sigma == MAGNITUDE_SIGMA
    # the episode count distribution is the recorded one
    counts = np.bincount([len(extract_episodes(s)) for s in sessions])
    assert stored.count_pmf is not None
    np.testing.assert_allclose(stored.count_pmf, counts / counts.sum(), atol=1e-4)


def test_closed_loop_score() -> None:
    centred = ClosedLoopScore({"ac": RATIO_CENTRE, "lc": RATIO_CENTRE}, (0.5, 0.8), (0.5, 0.8))
    assert centred.loss == pytest.approx(0.0, abs=1e-12)
    off = ClosedLoopScore({"ac": 0.9, "lc": 1.1}, (0.45, 0.8), (0.5, 0.8))
    worst = max(abs(math.log(0.9 / RATIO_CENTRE)), abs(math.log(1.1 / RATIO_CENTRE)))
    assert off.loss == pytest.approx(worst + 1.0)
    assert "loss" in off.line()


def test_write_params_round_trips(tmp_path: Path) -> None:
    params = SyntheticUserParams.calibrated()
    path = tmp_path / "sub" / "synthetic.yaml"
    write_params(params, path, "made by a test\nsecond line")
    text = path.read_text()
    assert text.startswith("# made by a test\n# second line\n")
    assert SyntheticUserParams.load(path) == params


def test_cli_rejects_bad_arguments(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit):
        main(["--sessions", str(tmp_path), "--seed", "5"])
    with pytest.raises(SystemExit):
        main(["--sessions", str(tmp_path), "--duration", "0,-1"])
    assert main(["--sessions", str(tmp_path)]) == 2  # no CSVs: a named error, no traceback
    assert "langctrl calibrate: error" in capsys.readouterr().err
    with pytest.raises(ConfigError, match="calibration seeds"):
        from eval.calibrate import closed_loop_fit

        closed_loop_fit(
            [], SyntheticUserParams.calibrated(), durations=[4.5], magnitudes=[9.0], seed=3
        )
