"""The speech timeline and its rendering with pause and filler vertices."""

from __future__ import annotations

import numpy as np
import pytest

from langenv.errors import ActionError, ConfigError
from langenv.speech.audio import ClipLibrary
from langenv.speech.graph import PhraseGraph
from langenv.speech.phrase import Phrase
from langenv.speech.render import plan_speech, render_history
from langenv.speech.timeline import SpeechTimeline

DT = 0.002


def graph() -> PhraseGraph:
    phrases = [
        Phrase("a", "Go.", None, ("wait",)),
        Phrase("wait", None, None, ("okay", "b"), "pause", (0.5, 2.0)),
        Phrase("okay", "Okay.", None, ("b",), "filler"),
        Phrase("b", "And you're done.", None, ()),
    ]
    return PhraseGraph(phrases, "a", {"a": 1.0, "okay": 0.5, "b": 1.0}, pause=0.5)


def run(tl: SpeechTimeline, seconds: float, a: float = 1.0, **kw: object) -> None:
    for _ in range(round(seconds / DT)):
        tl.step(DT, a, **kw)  # type: ignore[arg-type]


def test_a_pause_takes_the_rule_s_length_when_entered_and_counts_as_silence() -> None:
    tl = SpeechTimeline(graph())
    # t_x = 4 s: after 'a' (1.5 s with its gap) 2.5 s are left; the plan with the pause at
    # 1.25 s leaves 1.25 s: 'b' (mid 1.0) is chosen, so the pause lasts 2.5 - 1.0 = 1.5 s
    t_x = 4.0
    while tl.phrase != "wait":
        tl.step(DT, 1.0, t_x=t_x - tl.t)
    assert tl.in_pause and tl.fraction_said == 1.0
    assert tl.slot_length == pytest.approx(1.5, abs=0.01)
    assert tl.pause_lengths == (pytest.approx(0.0, abs=0.01),)  # elapsed so far
    assert tl.eta(t_x - tl.t) == pytest.approx(t_x - tl.t, abs=0.01)  # ends with the motion
    assert tl.said_at(tl.t - 0.001) is None
    while not tl.done:
        tl.step(DT, 1.0, t_x=max(0.0, t_x - tl.t))
    assert tl.path == ("a", "wait", "b")
    assert tl.t_end == pytest.approx(t_x, abs=0.01)
    assert tl.pause_lengths == (pytest.approx(1.5, abs=0.01),)
    utt = tl.utterances()
    assert [u.phrase for u in utt] == ["a", "wait", "b"]
    assert utt[1].length == tl.pause_lengths[0] and utt[0].length is None
    assert tl.content_time == pytest.approx(1.5 + 1.5 + 1.0, abs=0.01)


def test_an_open_pause_waits_while_the_motion_is_slow() -> None:
    """The pause is planned again at every step: a motion that stalls (t_x stays put) keeps the
    person waiting, up to the pause's maximum; one that speeds up ends it early."""
    stalled, quick = SpeechTimeline(graph()), SpeechTimeline(graph())
    for tl, rate in ((stalled, 0.0), (quick, 3.0)):
        t_x = 4.0
        while not tl.done:
            tl.step(DT, 1.0, t_x=t_x)
            if tl.phrase == "wait":
                t_x = max(0.0, t_x - rate * DT)
            else:
                t_x = max(0.0, t_x - DT)
    assert stalled.pause_lengths == (2.0,)  # waited to the maximum
    assert quick.pause_lengths[0] < 1.0  # the arm caught up: on with the speech


def test_a_given_target_sets_the_pause_within_its_bounds() -> None:
    tl = SpeechTimeline(graph())
    run(tl, 1.6, pause=9.0, choice="b")
    assert tl.phrase == "wait" and tl.slot_length == 2.0
    tl.reset()
    run(tl, 1.6, pause=0.1, choice="b")
    assert tl.phrase == "wait" and tl.slot_length == 0.5


def test_entering_a_pause_without_a_length_or_t_x_is_an_error_that_changes_nothing() -> None:
    tl = SpeechTimeline(graph())
    run(tl, 1.4)
    before = (tl.t, tl.position, tl.phrase, tl.path)
    with pytest.raises(ActionError, match="pause 'wait' is entered"):
        tl.step(0.2, 1.0)
    assert (tl.t, tl.position, tl.phrase, tl.path) == before
    with pytest.raises(ActionError, match="must be finite"):
        tl.step(0.2, 1.0, pause=float("nan"))
    assert (tl.t, tl.position, tl.phrase, tl.path) == before


def test_a_pause_elapses_at_the_audio_pace_like_the_gap_between_phrases() -> None:
    slow, fast = SpeechTimeline(graph()), SpeechTimeline(graph())
    for tl, a in ((slow, 0.8), (fast, 1.25)):
        while not tl.done:
            tl.step(DT, a, choice="b", pause=100.0)
    # content 1.5 + 2.0 + 1.0 s at a = 0.8 and at a = 1.25
    assert slow.t_end == pytest.approx(4.5 / 0.8, abs=0.01)
    assert fast.t_end == pytest.approx(4.5 / 1.25, abs=0.01)


def test_render_plays_a_pause_as_its_chosen_silence(clips: ClipLibrary) -> None:
    phrases = [
        Phrase("a", "Go.", None, ("wait",)),
        Phrase("wait", None, None, ("b",), "pause", (0.5, 3.0)),
        Phrase("b", "Done.", None, ()),
    ]
    dur = {u: clips.duration(p) for u, p in ((p.id, p) for p in phrases) if p.text}
    g = PhraseGraph(phrases, "a", dur, pause=0.3)
    t = np.linspace(0.0, 8.0, 401)
    a = np.ones_like(t)
    short = render_history(g, clips, ["a", "wait", "b"], t, a, pause_lengths=[0.5])
    long = render_history(g, clips, ["a", "wait", "b"], t, a, pause_lengths=[2.5])
    sr = clips.sr

    def last_sound(y: np.ndarray) -> float:
        return float(np.flatnonzero(np.abs(y) > 1e-3)[-1]) / sr

    assert last_sound(long) - last_sound(short) == pytest.approx(2.0, abs=0.05)
    # a plan with t_x picks the pause's length; the utterances carry it to the renderer
    plan = plan_speech(g, t, a, t_x=np.maximum(0.0, 3.5 - t))
    assert [u.phrase for u in plan] == ["a", "wait", "b"]
    assert plan[-1].t_end == pytest.approx(3.5, abs=0.03)  # t_x held over 20 ms steps
    y = render_history(g, clips, plan, t, a)
    assert last_sound(y) == pytest.approx(3.5, abs=0.05)
    with pytest.raises(ConfigError, match="pause 'wait' has no length"):
        render_history(g, clips, ["a", "wait", "b"], t, a)
    with pytest.raises(ConfigError, match="outside its bounds"):
        render_history(g, clips, ["a", "wait", "b"], t, a, pause_lengths=[9.0])
