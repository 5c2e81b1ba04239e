"""The analytic controllers as policies (policies/analytic.py): names, checks, EM feedback and the
terminal phase."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import langenv
from langenv.control.pacing import command_from_action
from langenv.errors import ConfigError
from langenv.task import observation as ob
from langenv.task.observation import Obs
from policies.analytic import (
    AdmittanceController,
    LanguageController,
    make_analytic,
)


def _obs(
    t_x: float,
    t_a: float,
    coop: float = 1.0,
    motion_done: bool = False,
    speech_done: bool = False,
    time: float = 0.0,
) -> np.ndarray:
    obs = np.zeros(ob.observation_size(1), np.float32)
    obs[Obs.T_X], obs[Obs.T_A] = ob.encode_seconds(t_x), ob.encode_seconds(t_a)
    obs[Obs.COOPERATION] = ob.encode_fraction(coop)
    obs[Obs.SPEECH_DONE] = ob.encode_flag(speech_done)
    obs[Obs.MOTION_DONE] = ob.encode_flag(motion_done)
    obs[Obs.ELAPSED] = ob.encode_elapsed(time)
    return obs


def test_names_build_the_right_controllers() -> None:
    assert isinstance(make_analytic("ac"), AdmittanceController)
    lc, noap, em = make_analytic("lc"), make_analytic("lc-noap"), make_analytic("lc-em")
    assert (lc.name, lc.graph_role, lc.decision_hz, lc.k_em) == ("lc", "graph", 500, 0.0)
    assert (noap.name, noap.graph_role) == ("lc-noap", "single")
    assert make_analytic("ac").graph_role == "single"
    assert (em.name, em.graph_role, em.k_em) == ("lc-em", "graph", 1.0)
    end = make_analytic("lc-end")
    assert isinstance(end, LanguageController)
    assert (end.name, end.graph_role, end.terminal, end.k_em, lc.terminal) == (
        "lc-end",
        "graph",
        1.0,
        0.0,
        0.0,
    )
    both = make_analytic("lc-em-end")
    assert (both.name, both.graph_role, both.k_em, both.terminal) == (
        "lc-em-end",
        "graph",
        1.0,
        1.0,
    )
    assert make_analytic("lc", decision_hz=25).decision_hz == 25
    with pytest.raises(KeyError, match="lc-em"):
        make_analytic("lq")


@pytest.mark.parametrize("field", ["k_em", "em_clip", "terminal"])
@pytest.mark.parametrize("bad", [-0.1, float("nan"), float("inf")])
def test_bad_feedback_parameters_raise(field: str, bad: float) -> None:
    with pytest.raises(ConfigError, match=field):
        LanguageController(**{field: bad})  # type: ignore[arg-type]


@settings(max_examples=60, deadline=None)
@given(
    t_x=st.floats(0.5, 30.0),
    t_a=st.floats(0.5, 30.0),
    coop=st.floats(0.0, 1.0),
    k=st.floats(0.0, 5.0),
)
def test_em_feedback_shifts_only_the_physical_pace(
    t_x: float, t_a: float, coop: float, k: float
) -> None:
    """``p_cmd = p* - clip(k EM, ±em_clip)`` while moving; the audio command is LC's."""
    lc, em = LanguageController(), LanguageController(k_em=k, em_clip=0.5)
    base, act = lc.act(_obs(t_x, t_a, coop)), em.act(_obs(t_x, t_a, coop))
    shift = float(np.clip(k * (t_a - t_x), -0.5, 0.5))
    p0, p1 = command_from_action(float(base[0]), 1.4), command_from_action(float(act[0]), 1.4)
    # the action map saturates at u = ±1 (p_cmd in [-1.5, 1.4])
    assert p1 == pytest.approx(float(np.clip(p0 - shift, -1.5, 1.4)), abs=1e-5)
    assert act[1] == base[1] and act[2] == base[2] == 0.0


def test_em_feedback_is_off_once_the_motion_is_over() -> None:
    lc, em = LanguageController(), LanguageController(k_em=2.0)
    obs = _obs(0.0, 3.0, motion_done=True)
    assert np.array_equal(lc.act(obs), em.act(obs))


def test_phases() -> None:
    lc, end = LanguageController(), LanguageController(terminal=1.0)
    cases = [
        (_obs(5.0, 5.0), "aligning", "aligning"),
        (_obs(0.8, 0.9), "aligning", "terminal"),
        (_obs(0.0, 0.5, motion_done=True), "aligning", "finishing"),
        (_obs(0.5, 0.0, speech_done=True), "aligning", "finishing"),
        (_obs(0.0, 0.0, motion_done=True, speech_done=True), "over", "over"),
    ]
    for obs, want_lc, want_end in cases:
        assert (lc.phase(obs), end.phase(obs)) == (want_lc, want_end)


def test_terminal_phase_matches_the_speech_to_the_observed_motion_rate() -> None:
    """``p_cmd = 1`` and ``a_cmd = t_a r / t_x`` with ``r`` the observed rate of ``t_x``."""
    end = LanguageController(terminal=1.0, decision_hz=25)
    end.reset()
    # the hand moves at half the rate t_x assumes, for long enough to settle the estimate
    t_x, t = 0.9, 10.0
    for _ in range(60):
        act = end.act(_obs(t_x, 0.6, time=t))
        t_x, t = t_x - 0.5 * 0.01, t + 0.01
    assert end.motion_rate == pytest.approx(0.5, rel=1e-3)
    assert command_from_action(float(act[0]), 1.4) == pytest.approx(1.0)
    t_x_last = t_x + 0.005
    want = 0.6 * end.motion_rate / t_x_last
    assert command_from_action(float(act[1]), 1.4) == pytest.approx(want, rel=1e-3)
    again = end.act(_obs(t_x_last, 0.6, time=t - 0.01))  # the same observation: no new estimate
    assert end.motion_rate == pytest.approx(0.5, rel=1e-3) and np.array_equal(again, act)
    end.reset()
    assert end.motion_rate == 1.0


def test_finishing_phase_ends_the_other_channel_as_fast_as_allowed() -> None:
    end = LanguageController(terminal=1.0)
    talk = end.act(_obs(0.0, 0.5, motion_done=True))
    move = end.act(_obs(0.5, 0.0, speech_done=True))
    assert command_from_action(float(talk[1]), 1.4) == pytest.approx(1.4)
    assert command_from_action(float(move[0]), 1.4) == pytest.approx(1.4)


@pytest.mark.parametrize("hz", [25, 500])
@pytest.mark.parametrize("push", [0.0, -20.0])
def test_terminal_phase_ends_speech_and_motion_together(hz: int, push: float) -> None:
    """Closed loop: with the terminal phase |AM| is a few ms, well below LC's on the same user.

    On the plant fitted to the recordings (the hand brakes to rest at the end) and the study's
    phrase graph it measures 3-9 ms against LC's 250-270 ms: within a quarter of a 25 Hz
    decision step. (On the default graph LC's own final pause already ends together.)"""
    import gymnasium as gym

    results = {}
    for name in ("lc", "lc-end"):
        pol = make_analytic(name, decision_hz=hz)
        env = gym.make(
            langenv.ENV_ID,
            phrase_graph="study",
            decision_hz=hz,
            max_episode_steps=60 * hz,
            users=lambda t, v, b, push=push: push * b if 4.0 < t < 7.0 else 0.0 * b,
        )
        obs, _ = env.reset(seed=0)
        pol.reset()
        done, info = False, {}
        while not done:
            obs, _, term, trunc, info = env.step(pol.act(obs))
            done = term or trunc
        assert term
        results[name] = abs(info["am"])
    assert results["lc-end"] < 0.01
    assert results["lc-end"] < 0.1 * results["lc"]
