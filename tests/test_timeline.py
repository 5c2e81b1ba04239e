"""Speech timeline: playback at pace a, pauses, choices, history, consistency with eta."""

from __future__ import annotations

from typing import TypeAlias

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from langenv.errors import ActionError
from langenv.speech.graph import PhraseGraph
from langenv.speech.phrase import Phrase
from langenv.speech.timeline import SpeechTimeline, Utterance

DT = 0.002
Dag: TypeAlias = tuple[dict[str, tuple[str, ...]], dict[str, float], float]


def graph(
    nxt: dict[str, tuple[str, ...]], dur: dict[str, float], pause: float = 1.0
) -> PhraseGraph:
    return PhraseGraph([Phrase(u, u, None, k) for u, k in nxt.items()], "p0", dur, pause=pause)


# p0 -> {p1 (short) | p2 (long)} -> p3
FORK = graph(
    {"p0": ("p1", "p2"), "p1": ("p3",), "p2": ("p3",), "p3": ()},
    {"p0": 1.0, "p1": 0.5, "p2": 3.0, "p3": 0.8},
    pause=0.4,
)


def run(tl: SpeechTimeline, a: float, limit: float = 100.0, **kw: object) -> None:
    while not tl.done and tl.t < limit:
        tl.step(DT, a, **kw)  # type: ignore[arg-type]


@st.composite
def dags(draw: st.DrawFn) -> tuple[dict[str, tuple[str, ...]], dict[str, float], float]:
    n = draw(st.integers(1, 7))
    ids = [f"p{i}" for i in range(n)]
    nxt = {}
    for i, u in enumerate(ids):
        later = ids[i + 1 :]
        nxt[u] = (
            tuple(draw(st.lists(st.sampled_from(later), unique=True, max_size=3))) if later else ()
        )
    dur = {u: draw(st.floats(0.05, 3.0)) for u in ids}
    return nxt, dur, draw(st.sampled_from([0.0, 0.25, 1.0]))


def test_history_at_pace_one_is_clips_and_pauses() -> None:
    tl = SpeechTimeline(FORK)
    run(tl, 1.0, choice="p2")
    assert tl.done and tl.phrase is None
    assert [u.phrase for u in tl.history] == ["p0", "p2", "p3"]
    expected = [(0.0, 1.0), (1.4, 4.4), (4.8, 5.6)]
    for utt, (t0, t1) in zip(tl.history, expected, strict=True):
        assert utt.t_start == pytest.approx(t0, abs=1e-9)
        assert utt.t_end == pytest.approx(t1, abs=1e-9)
    assert tl.t_end == pytest.approx(5.6, abs=1e-9)
    assert tl.path == ("p0", "p2", "p3")


@settings(max_examples=100, deadline=None)
@given(dags(), st.floats(0.6, 1.4), st.sampled_from([0.002, 0.01, 0.04]))
def test_speech_lasts_its_path_length_over_a(dag: Dag, a: float, dt: float) -> None:
    nxt, dur, pause = dag
    g = graph(nxt, dur, pause)
    tl = SpeechTimeline(g)
    n = 0
    while not tl.done:
        tl.step(dt, a, choice=lambda kids: kids[-1])
        n += 1
        assert n < 1e6
    path = tl.path
    assert [u.phrase for u in tl.history] == list(path)
    assert tl.t_end == pytest.approx(g.path_length(path) / a, abs=1e-9)
    for u in tl.history:
        assert u.duration == pytest.approx(dur[u.phrase] / a, abs=1e-9)
    assert tl.content_time == pytest.approx(g.path_length(path), abs=1e-9)


@settings(max_examples=100, deadline=None)
@given(dags(), st.floats(0.0, 25.0), st.sampled_from([0.002, 0.02]))
def test_rule_with_t_x_falling_at_base_pace_realises_eta(dag: Dag, t0: float, dt: float) -> None:
    """At a = 1 with t_x(t) = T0 - t, the timeline says exactly what eta predicted at t = 0."""
    nxt, dur, pause = dag
    g = graph(nxt, dur, pause)
    # skip near-ties of the rule, where rounding could flip a choice
    u, left = "p0", t0 - g.slot("p0")
    while g.children(u):
        errs = sorted(abs(left - 0.5 * (g.t_min(v) + g.t_max(v))) for v in g.children(u))
        assume(len(errs) == 1 or errs[1] - errs[0] > 1e-6)
        u = g.choose(u, left)
        left -= g.slot(u)
    eta0 = g.eta("p0", g.slot("p0"), t0)
    tl = SpeechTimeline(g)
    assert tl.eta(t0) == pytest.approx(eta0)
    while not tl.done:
        tl.step(dt, 1.0, t_x=t0 - tl.t)
        if not tl.done:
            assert tl.eta(t0 - tl.t) == pytest.approx(eta0 - tl.t, abs=1e-6)
    assert tl.t_end == pytest.approx(eta0, abs=1e-9)
    assert tl.eta(0.0) == 0.0


def test_pauses_elapse_at_pace_a() -> None:
    tl = SpeechTimeline(FORK)
    run(tl, 0.5, choice="p1")
    starts = [u.t_start for u in tl.history]
    ends = [u.t_end for u in tl.history]
    assert starts[1] - ends[0] == pytest.approx(0.4 / 0.5)
    assert tl.t_end == pytest.approx((1.0 + 0.4 + 0.5 + 0.4 + 0.8) / 0.5)


def test_choice_by_id_callable_and_rule() -> None:
    for choice, t_x, expected in [
        ("p1", None, "p1"),
        ("p2", None, "p2"),
        (lambda kids: kids[1], None, "p2"),
        (None, 2.0, "p1"),  # mid(p1) = 0.5+0.4+0.8 = 1.7, mid(p2) = 4.2
        (None, 10.0, "p2"),
    ]:
        tl = SpeechTimeline(FORK)
        run(tl, 1.0, choice=choice, t_x=t_x)
        assert tl.path[1] == expected


def test_callable_choice_sees_candidates_only_at_the_boundary() -> None:
    seen: list[tuple[str, ...]] = []

    def pick(kids: tuple[str, ...]) -> str:
        seen.append(kids)
        return kids[0]

    tl = SpeechTimeline(FORK)
    run(tl, 1.0, choice=pick)
    assert seen == [("p1", "p2")]  # p1 -> p3 has a single child: no call


def test_invalid_choice_raises_and_leaves_the_timeline_unchanged() -> None:
    tl = SpeechTimeline(FORK)
    while tl.remaining_in_phrase > 0.01:
        tl.step(DT, 1.0)  # no boundary yet: no choice needed
    state = (tl.t, tl.phrase, tl.position, tl.in_pause, len(tl.history))
    with pytest.raises(ActionError, match="'p3' is not a child of phrase 'p0'"):
        tl.step(0.1, 1.0, choice="p3")
    with pytest.raises(ActionError, match="'zz' is not a child"):
        tl.step(0.1, 1.0, choice=lambda kids: "zz")
    with pytest.raises(ActionError, match="pass `choice` or `t_x`"):
        tl.step(0.1, 1.0)
    assert (tl.t, tl.phrase, tl.position, tl.in_pause, len(tl.history)) == state
    tl.step(0.1, 1.0, choice="p2")
    assert tl.phrase == "p2"


@pytest.mark.parametrize(
    ("dt", "a"), [(0.0, 1.0), (-1.0, 1.0), (np.nan, 1.0), (DT, -0.1), (DT, np.inf), (DT, np.nan)]
)
def test_bad_step_arguments_raise(dt: float, a: float) -> None:
    tl = SpeechTimeline(FORK)
    with pytest.raises(ActionError):
        tl.step(dt, a)


def test_state_queries_along_a_phrase() -> None:
    tl = SpeechTimeline(FORK)
    assert tl.phrase == "p0" and not tl.in_pause and tl.fraction_said == 0.0
    assert tl.candidates == ("p1", "p2")
    assert tl.remaining_in_phrase == pytest.approx(1.4)
    for _ in range(250):
        tl.step(DT, 1.0)
    assert tl.fraction_said == pytest.approx(0.5)
    assert tl.remaining_audio == pytest.approx(0.5)
    assert tl.said_at(0.2) == "p0"
    assert not tl.boundary_due(0.5)
    assert tl.boundary_due(1.0)
    assert tl.boundary_due(0.5, a=2.0)
    for _ in range(300):
        tl.step(DT, 1.0)
    assert tl.in_pause and tl.fraction_said == 1.0 and tl.phrase == "p0"
    assert tl.remaining_in_phrase == pytest.approx(0.3)
    assert tl.said_at(1.05) is None  # in the pause
    run(tl, 1.0, choice="p1")
    assert tl.said_at(1.5) == "p1"
    assert tl.said_at(1.0 + 0.4 + 0.5 + 0.4 + 0.1) == "p3"
    assert tl.said_at(-1.0) is None and tl.said_at(100.0) is None
    assert not tl.boundary_due(10.0)
    assert tl.candidates == () and tl.remaining_in_phrase == 0.0
    t = tl.t
    tl.step(DT, 1.0)  # after the end only time advances
    assert tl.t == pytest.approx(t + DT) and tl.done


def test_final_phrase_needs_no_choice_and_has_no_pause() -> None:
    g = graph({"p0": ()}, {"p0": 2.0})
    tl = SpeechTimeline(g)
    assert not tl.boundary_due(100.0)
    run(tl, 1.0)
    assert tl.t_end == pytest.approx(2.0)
    (only,) = tl.history
    assert only.phrase == "p0" and only.t_start == 0.0
    assert only.t_end == pytest.approx(2.0)


def test_reset_restarts() -> None:
    tl = SpeechTimeline(FORK)
    run(tl, 1.3, choice="p2")
    tl.reset()
    assert tl.t == 0.0 and tl.phrase == "p0" and not tl.done and tl.history == []
    assert tl.utterances() == [Utterance("p0", 0.0, 0.0)]


def test_utterances_include_the_phrase_in_progress() -> None:
    tl = SpeechTimeline(FORK)
    for _ in range(100):
        tl.step(DT, 1.0)
    (u,) = tl.utterances()
    assert u.phrase == "p0" and u.t_end == pytest.approx(0.2)
