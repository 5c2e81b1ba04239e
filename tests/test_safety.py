"""The safety layer: limits, the commanded-velocity limiter, the monitor and protective stops."""

from __future__ import annotations

import math
from typing import Any

import gymnasium as gym
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import langenv
from bench.safety import ADVERSARIES, DEVIATION_SLACK, SPEED_SLACK, FuzzResult, fuzz_episode
from langenv.control.admittance import AdmittanceParams
from langenv.control.cooperation import CooperationFilter
from langenv.control.trajectory import default_exercise
from langenv.errors import ConfigError
from langenv.exercise import speak
from langenv.motion.tick import GuidedArm
from langenv.robot.arm import Arm
from langenv.robot.force_sensor import ForceSensor
from langenv.robot.safety import (
    HOLD_TIME,
    JOINT_CHECK_MAX,
    STOP_LIMITS,
    SafetyLimits,
    SafetyMonitor,
    SafetyStop,
    limit_velocity,
)
from langenv.users import CallableUser
from policies import load_policy

LIMITS = SafetyLimits()


def test_defaults_fit_a_therapy_exercise() -> None:
    assert LIMITS.max_speed <= 0.5
    assert LIMITS.max_deviation <= 0.10
    assert LIMITS.max_force <= 150.0
    assert LIMITS.hold_deviation < LIMITS.max_deviation


@pytest.mark.parametrize(
    ("kwargs", "field"),
    [
        ({"max_speed": 0.0}, "max_speed"),
        ({"max_force": -1.0}, "max_force"),
        ({"max_deviation": math.nan}, "max_deviation"),
        ({"speed_tolerance": -0.1}, "speed_tolerance"),
        ({"hold_deviation": 0.2}, "hold_deviation"),
        ({"joint_margin": "0.1"}, "joint_margin"),
        ({"max_speed": True}, "max_speed"),
    ],
)
def test_bad_limits_name_the_field(kwargs: dict[str, Any], field: str) -> None:
    with pytest.raises(ConfigError, match=f"SafetyLimits.{field}"):
        SafetyLimits(**kwargs)


vectors = st.lists(st.floats(-5.0, 5.0), min_size=3, max_size=3).map(np.array)
offsets = st.lists(st.floats(-0.3, 0.3), min_size=3, max_size=3)


@settings(max_examples=300, deadline=None)
@given(v=vectors, offset=offsets)
def test_limited_velocity_respects_speed_and_hold(v: np.ndarray, offset: list[float]) -> None:
    out = limit_velocity(v, offset, LIMITS)
    assert float(np.linalg.norm(out)) <= LIMITS.max_speed * (1 + 1e-12)
    d = math.dist(offset, (0.0, 0.0, 0.0))
    if d > 1e-9:
        n = np.asarray(offset) / d
        cap = max(0.0, (LIMITS.hold_deviation - d) / HOLD_TIME)
        assert float(out @ n) <= cap + 1e-9
        # the component along the path (across the offset) is never increased
        assert np.linalg.norm(out - (out @ n) * n) <= np.linalg.norm(v - (v @ n) * n) + 1e-12


def test_velocity_within_the_limits_is_left_alone() -> None:
    v = np.array([0.1, -0.05, 0.0])
    assert limit_velocity(v, (0.0, 0.01, 0.0), LIMITS) is v
    capped = limit_velocity(v, (0.2, 0.0, 0.0), LIMITS)  # +x is away from the path: capped
    assert np.allclose(capped, [0.0, -0.05, 0.0], atol=1e-15)
    inward = limit_velocity(v, (0.0, 0.2, 0.0), LIMITS)  # -y points back to the path
    assert np.allclose(inward, v)


def test_monitor_names_each_limit() -> None:
    mon = SafetyMonitor(LIMITS, 0.002)
    assert mon.check(1.0, 0.2, 0.01, 20.0) is None
    assert mon.check(1.0, 0.5 + LIMITS.speed_tolerance, 0.01, 20.0) is None  # tolerance
    cases = {
        "force": (0.1, 0.0, 150.5),
        "path_deviation": (0.1, 0.1001, 0.0),
        "speed": (0.53, 0.0, 0.0),
    }
    for limit, (speed, dev, force) in cases.items():
        stop = mon.check(2.5, speed, dev, force)
        assert stop is not None and stop.limit == limit
        assert "protective stop at t=2.500 s" in stop.message
    nan = mon.check(0.0, math.nan, 0.0, 0.0)
    assert nan is not None and nan.limit == "speed"


def test_monitor_catches_a_joint_reaching_its_range_end() -> None:
    lo, hi = np.array([-1.0, -2.0]), np.array([1.0, 2.0])
    mon = SafetyMonitor(LIMITS, 0.002, lo, hi, ("elbow", "wrist"))
    reads: list[int] = []

    def still() -> np.ndarray:
        reads.append(1)
        return np.zeros(2)

    # far from the ends, the joints need not be read every tick ...
    for _ in range(2 * JOINT_CHECK_MAX):
        assert mon.check(0.0, 0.0, 0.0, 0.0, still) is None
    assert 2 <= len(reads) <= 3
    # ... but a joint moving at the speed bound is caught at the first tick past its margin,
    # as if it were checked every tick
    mon.reset()
    step = 4 * math.pi * 0.002
    first_past = next(k for k in range(10_000) if 1.0 + step * k > 2.0 - LIMITS.joint_margin)
    for k in range(10_000):
        stop = mon.check(k * 0.002, 0.0, 0.0, 0.0, lambda k=k: np.array([0.0, 1.0 + step * k]))
        if stop is not None:
            break
    assert k == first_past
    assert stop is not None and stop.limit == "joint_limit" and "wrist" in stop.message


@pytest.fixture(scope="module")
def motion() -> GuidedArm:
    """A guided arm with a lower speed limit (building one takes a while: shared)."""
    limits = SafetyLimits(max_speed=0.3, hold_deviation=0.05)
    return GuidedArm(
        Arm(), default_exercise(), AdmittanceParams(), ForceSensor(), CooperationFilter(), limits
    )


def test_speed_limit_has_one_source(motion: GuidedArm) -> None:
    assert motion.arm.max_hand_speed == 0.3
    assert Arm().max_hand_speed == SafetyLimits().max_speed


def test_protective_stop_halts_and_holds_the_arm(motion: GuidedArm) -> None:
    motion.reset()
    push = np.array([0.0, 0.0, 160.0])
    motion.tick(push, 1.0, 0.0)
    assert motion.stopped and motion.safety_stop is not None
    assert motion.safety_stop.limit == "force"
    x0 = motion.hand_position
    for _ in range(500):  # 1 s more, the person still pushing (30 N): the arm holds still
        motion.tick(push * 30.0 / 160.0, 1.0, 0.0)
    assert float(np.linalg.norm(motion.hand_position - x0)) < 0.01
    assert motion.hand_speed < 0.01
    assert motion.v_ref.tolist() == [0.0, 0.0, 0.0]
    assert motion.safety_stop.limit == "force"  # the first breach stays the reason
    motion.reset()
    assert not motion.stopped


_ENVS: dict[str, Any] = {}


def _episode(user: Any, policy: str = "lc", steps: int | None = None) -> list[dict[str, Any]]:
    """An episode of ``policy`` with ``user``, whole (60 s at most) or its first ``steps``
    steps; the infos of every step."""
    pol = load_policy(policy)
    env = _ENVS.get(policy)
    if env is None:  # one env per policy: building one takes a while
        env = _ENVS[policy] = gym.make(langenv.ENV_ID, phrase_graph=speak(pol).ref)
    obs, info = env.reset(seed=0, options={"user": CallableUser(user)})
    pol.reset()
    infos = [info]
    done = steps == 0
    while not done:
        obs, _r, terminated, truncated, info = env.step(pol.act(obs))
        infos.append(dict(info, terminated=terminated))
        done = terminated or truncated or len(infos) - 1 == steps
    return infos


def test_the_issue_repro_ends_in_a_protective_stop() -> None:
    """A person pushing 200 N along the hand's velocity: stopped, never beyond the limits."""
    infos = _episode(lambda t, v, b: 200 * np.asarray(v) / max(np.linalg.norm(v), 1e-3))
    last = infos[-1]
    assert last["terminated"] and last["safety_stop"] in STOP_LIMITS
    assert last["safety_message"].startswith("protective stop at t=")
    assert last["am"] is None and last["reward_am"] == 0.0
    for info in infos[:-1]:
        assert info["safety_stop"] is None and info["safety_message"] == ""
        assert info["max_hand_speed"] <= LIMITS.max_speed + LIMITS.speed_tolerance
        assert info["path_deviation"] <= LIMITS.max_deviation


def test_info_reports_deviation_and_top_speed_every_step() -> None:
    _episode(lambda t, v, b: np.zeros(3), "lc", steps=0)  # builds the env
    env = _ENVS["lc"]
    _obs, info = env.reset(seed=0, options={"user": CallableUser(lambda t, v, b: np.zeros(3))})
    assert info["path_deviation"] < 1e-6
    base: Any = env.unwrapped
    top = 0.0
    for _ in range(50):
        _obs, _r, _te, _tr, info = env.step(np.zeros(3, np.float32))
        m = base.motion
        dev = float(np.linalg.norm(m.hand_position - m.trajectory.position(m.state.s)))
        assert info["path_deviation"] == pytest.approx(dev, abs=2e-4)  # s lags one tick
        assert info["max_hand_speed"] >= info["hand_speed"]
        top = max(top, info["max_hand_speed"])
    assert 0.05 < top < 0.2  # the guided hand moves at its plateau speed


def test_fuzz_adversarial_users() -> None:
    """Seeded adversarial users (up to 200 N), short episodes: no crash, no NaN, and every step
    within the speed limit (+5 %) and the deviation limit (+1 cm), or a protective stop saying
    why. ``python -m bench.safety`` runs the long version."""
    result = FuzzResult()
    for k, kind in enumerate(ADVERSARIES):
        for j, policy in enumerate(("lc", "random")):
            fuzz_episode(1000 + 2 * k + j, result, seconds=6.0, kind=kind, policy=policy)
    assert result.violations == []
    assert result.episodes == 2 * len(ADVERSARIES)
    assert result.stops["force"] >= 1  # 200 N users are stopped
    assert sum(result.stops.values()) < result.episodes  # and not every user is
    assert result.max_speed_unstopped <= LIMITS.max_speed * (1 + SPEED_SLACK)
    assert result.max_deviation_unstopped <= LIMITS.max_deviation + DEVIATION_SLACK


def test_stop_message_for_a_joint() -> None:
    stop = SafetyStop("joint_limit", 0.004, 0.01, 1.25, "elbow")
    assert stop.message == (
        "protective stop at t=1.250 s: joint elbow is 0.004 rad from the end of its range "
        "(margin 0.01 rad)"
    )


def _gentle(kind: str) -> Any:
    if kind == "along":
        return lambda t, v, b: 15.0 * np.asarray(b)
    if kind == "against":
        return lambda t, v, b: -15.0 * np.asarray(b)
    # switches between helping and resisting with a varying force up to 15 N
    return lambda t, v, b: 15.0 * math.sin(0.7 * t) * abs(math.sin(2.3 * t)) * np.asarray(b)


@pytest.mark.slow
@pytest.mark.parametrize("policy", ["lc", "ac"])
@pytest.mark.parametrize("kind", ["along", "against", "switching"])
def test_gentle_user_is_never_stopped(policy: str, kind: str) -> None:
    """A person pushing at most 15 N along or against the path, over a whole (60 s) episode."""
    infos = _episode(_gentle(kind), policy)
    assert all(info["safety_stop"] is None for info in infos)
    assert max(info["path_deviation"] for info in infos) <= LIMITS.hold_deviation + 0.005
