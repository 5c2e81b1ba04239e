"""lc-coach (policies.coach): the therapist's rule, reading the children's intents off the
observation, and choosing by intent without breaking the per-leg law."""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest

import langenv
from langenv.errors import ConfigError
from langenv.exercise.script import speak
from policies import load_policy
from policies.analytic import ANALYTIC, LanguageController
from policies.coach import ChildIntents, CoachRule

EXERCISE = "shoulder_extension"  # the validation exercise


@pytest.mark.parametrize(
    ("c", "trend", "pace", "want"),
    [
        (0.5, -0.5, 1.0, "relax"),  # low and falling: pushing against the path
        (0.5, 0.1, 1.0, "encourage"),  # low but recovering
        (0.8, -0.5, 1.0, "encourage"),  # falling from high
        (0.95, 0.0, 0.7, "faster"),
        (0.95, 0.0, 1.3, "slower"),
        (0.95, 0.0, 1.0, "guide"),
    ],
)
def test_the_rule_in_its_order(c: float, trend: float, pace: float, want: str) -> None:
    assert CoachRule().intent(c, trend, pace) == want


def test_the_rule_never_asks_for_pace_with_an_infinite_band() -> None:
    rule = CoachRule(pace_band=math.inf)
    assert rule.intent(0.95, 0.0, 0.1) == rule.intent(0.95, 0.0, 5.0) == "guide"


@pytest.mark.parametrize(
    "bad",
    [
        {"relax_c": 1.5},
        {"relax_trend": 0.1},
        {"pace_tau": 0.0},
        {"slack": -1.0},
        {"pace_band": "x"},
    ],
)
def test_the_rule_refuses_bad_thresholds(bad: dict[str, object]) -> None:
    with pytest.raises(ConfigError, match=next(iter(bad))):
        CoachRule(**bad)  # type: ignore[arg-type]


def test_lc_coach_is_registered_with_lc_fill_end_s_settings() -> None:
    coach, base = load_policy("lc-coach"), load_policy("lc-fill-end")
    assert "lc-coach" in ANALYTIC and coach.intents and not base.intents
    for name in ("choice", "fill_margin", "fill_anticipate", "pause_scale", "terminal", "gains"):
        assert getattr(coach, name) == getattr(base, name), name
    with pytest.raises(ConfigError, match="fill"):
        LanguageController(choice="mid", intents=True)


def _env(policy: object, users: str = "listening") -> tuple[gym.Env, object]:
    spoken = speak(policy, EXERCISE)
    env = gym.make(
        langenv.ENV_ID, exercise=EXERCISE, phrase_graph=spoken.ref, users=users, decision_hz=500
    )
    return env, env.unwrapped


def test_child_intents_are_the_env_s_candidates_intents() -> None:
    coach = load_policy("lc-coach")
    env, base = _env(coach)
    reader = ChildIntents(base.graph)
    obs, _ = env.reset(seed=900000)
    seen = 0
    for _ in range(40000):
        kids = base.speech.candidates
        if len(kids) >= 2:
            assert reader.of(obs) == tuple(base.graph.intent(c) for c in kids)
            seen += 1
        obs, _, terminated, truncated, _ = env.step(np.zeros(3, np.float32))
        if terminated or truncated:
            break
    assert seen > 100
    env.close()


def _episode(policy: object, seed: int) -> tuple[list[str], float, float]:
    env, base = _env(policy)
    obs, _ = env.reset(seed=seed)
    policy.reset()  # type: ignore[attr-defined]
    done = False
    while not done:
        obs, _, terminated, truncated, info = env.step(policy.act(obs))  # type: ignore[attr-defined]
        done = terminated or truncated
    path = list(base.speech.path)
    env.close()
    return path, float(info["t_motion"]), float(info["am"])


def test_without_a_graph_the_coach_is_lc_fill_end() -> None:
    blind = load_policy("lc-coach")
    blind.use_graph = None  # speak() skips it: the coach cannot read intents
    assert _episode(blind, 900001) == _episode(load_policy("lc-fill-end"), 900001)


def test_the_coach_says_the_wanted_intent_and_keeps_the_law() -> None:
    """A rule that always wants ``encourage`` (cooperation below 1, never pushing against):
    more encouraging words than lc-fill-end's, speech and motion still end together."""
    coach = load_policy("lc-coach")
    coach.rule = CoachRule(relax_c=0.0, encourage_c=1.0)
    path, _, am = _episode(coach, 900002)
    assert abs(am) <= 1.0
    assert coach.said and {want for _, want, _ in coach.said} <= {"encourage", "guide"}
    base_path, _, _ = _episode(load_policy("lc-fill-end"), 900002)
    env, base = _env(coach)
    graph = base.graph
    env.close()

    def asked(p: list[str]) -> int:
        return sum(graph.kind(u) == "phrase" and graph.intent(u) == "encourage" for u in p)

    assert asked(path) > asked(base_path)
