"""Synthetic and replayed users in the real env (LangCtrl-v0): determinism and session length.

A few 25 Hz sessions; the full comparison with the recordings is ``langctrl fidelity``.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import pytest

import langenv  # noqa: F401  (registers LangCtrl-v0)
from langenv.exercise import speak
from langenv.users import ReplayUser, SyntheticUser
from policies import load_policy

SESSIONS = Path(__file__).parents[2] / "shared" / "sessions"
NOMINAL = 10.1  # s, the default exercise without resistance


def _session(seed: int, user: Any = None, policy: str = "lc") -> dict[str, Any]:
    pol = load_policy(policy)
    pol.decision_hz = 25
    env = gym.make("LangCtrl-v0", phrase_graph=speak(pol).ref, decision_hz=25)
    obs, info = env.reset(seed=seed, options={"user": user} if user is not None else None)
    pol.reset()
    coop = [info["cooperation"]]
    done = False
    while not done:
        obs, _, terminated, truncated, info = env.step(pol.act(obs))
        coop.append(info["cooperation"])
        done = terminated or truncated
    base: Any = env.unwrapped
    return {"info": info, "coop": np.array(coop), "user": base.user, "truncated": truncated}


def test_env_synthetic_user_same_seed_same_session() -> None:
    a, b, c = _session(1001), _session(1001), _session(1002)
    assert not a["truncated"]
    assert a["info"]["t_motion"] == b["info"]["t_motion"]
    assert a["info"]["am"] == b["info"]["am"]
    np.testing.assert_array_equal(a["coop"], b["coop"])
    assert a["info"]["t_motion"] != c["info"]["t_motion"] or not np.array_equal(
        a["coop"], c["coop"]
    )


@pytest.mark.slow
def test_env_synthetic_sessions_resist_and_end_in_time() -> None:
    for seed in range(1010, 1014):
        res = _session(seed)
        user = res["user"]
        assert isinstance(user, SyntheticUser)
        assert not res["truncated"]
        # every calibrated user resists at the start, so every session is slowed down, but by
        # no more than the slowest recording (37 s)
        assert NOMINAL < res["info"]["t_motion"] < 37.0
        assert 1 <= len(user.episodes)
        assert res["coop"].min() < 0.9
        assert np.all((res["coop"] >= 0.0) & (res["coop"] <= 1.0))


def test_env_replay_keeps_speech_and_motion_together() -> None:
    if not SESSIONS.is_dir():
        pytest.skip(f"recorded sessions not found at {SESSIONS}")
    res = _session(0, ReplayUser.from_csv(SESSIONS / "u2_lc.csv"))
    assert not res["truncated"]
    assert abs(res["info"]["am"]) < 1.0  # LC keeps speech and motion together
