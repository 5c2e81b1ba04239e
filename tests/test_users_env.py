"""Synthetic users in the real env (LangCtrl-v0): determinism and session length.

A few 25 Hz sessions (about 1 s each); the full comparison with the replays of the recordings is
``python -m langenv.users.calibration --env``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from langenv.errors import ConfigError
from langenv.users.calibration import (
    CALIBRATED_PARAMS,
    EnvSummary,
    EnvUserSpec,
    run_env_session,
    run_env_sessions,
)

SESSIONS = Path(__file__).parents[2] / "shared" / "sessions"
NOMINAL = 11.0  # s, a little under the exercise's nominal time without resistance (about 11.5 s)


def test_env_synthetic_user_same_seed_same_session() -> None:
    a = run_env_session(EnvUserSpec.synthetic(1001), "lc")
    b = run_env_session(EnvUserSpec.synthetic(1001), "lc")
    c = run_env_session(EnvUserSpec.synthetic(1002), "lc")
    assert a.finished and b.finished and c.finished
    assert a.motion_time == b.motion_time
    assert a.am == b.am
    np.testing.assert_array_equal(a.cooperation, b.cooperation)
    assert a.motion_time != c.motion_time or not np.array_equal(a.cooperation, c.cooperation)


def test_env_synthetic_sessions_resist_and_end_in_time() -> None:
    specs = [EnvUserSpec.synthetic(seed) for seed in range(1010, 1016)]
    results = run_env_sessions(specs, ("lc",), progress=False)
    summary = EnvSummary.of(results)
    print(summary.line("synthetic / lc"))
    assert summary.finished == len(specs)
    assert CALIBRATED_PARAMS.count_pmf is not None
    max_count = len(CALIBRATED_PARAMS.count_pmf) - 1
    for res in results:
        # Every calibrated user resists at the start, so every session is slowed down, but by
        # no more than the slowest recordings replayed through the same env (47 s).
        assert NOMINAL < res.motion_time < 47.0
        assert 1 <= res.episodes <= max_count
        assert res.cooperation.min() < 0.9
        assert np.all((res.cooperation >= 0.0) & (res.cooperation <= 1.0))
    # The hand mostly creeps forward: it moves backwards for a small share of the motion.
    assert summary.backward_share < 0.3


def test_env_replay_spec_and_validation() -> None:
    with pytest.raises(ConfigError, match="exactly one"):
        EnvUserSpec("nobody", 0)
    with pytest.raises(ConfigError, match="empty"):
        EnvSummary.of([])
    if not SESSIONS.is_dir():
        pytest.skip(f"recorded sessions not found at {SESSIONS}")
    res = run_env_session(EnvUserSpec.replay(SESSIONS / "u2_lc.csv"), "lc")
    assert res.user == "u2_lc"
    assert res.finished
    assert res.episodes >= 1
    assert abs(res.am) < 1.0  # LC keeps speech and motion together for a recorded user
