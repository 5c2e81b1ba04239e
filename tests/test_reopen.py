"""The speech goes on after its end when the motion goes back (langenv.speech.repeat's
REOPEN_AFTER): where, when, the same in Python and compiled ticks, heard live and offline."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import pytest

import langenv
from langenv.errors import ConfigError
from langenv.exercise.script import speak
from langenv.speech.audio import ClipLibrary
from langenv.speech.graph import PhraseGraph, graph_path
from langenv.speech.phrase import Phrase
from langenv.speech.render import render_history
from langenv.speech.repeat import REOPEN_AFTER, Repeat, reopen_vertex
from langenv.speech.timeline import SpeechTimeline, Utterance
from policies.analytic import make_analytic

# A forearm_rotation person (validation seeds) who pushes the hand back by about 3 s of motion
# after "And you're done." has begun: before the speech went on, LC ended 3.7 s apart.
PUSHED_BACK = 800092
# A person of the new user's two-leg reach (a plain script, no repeat line) who pushes the hand
# back 0.2 m after "And you're done." began: -14.4 s before.
PUSHED_BACK_PLAIN = 7811
DATA = Path(__file__).parent / "data" / "exercises"


def test_the_reopen_vertex_is_the_shortest_first_saying_leading_to_the_last_phrase() -> None:
    assert PhraseGraph.load(graph_path("default")).reopen == "keep_going_3"
    assert PhraseGraph.load(graph_path("study")).reopen is None  # the paper's graph: unchanged


def _graph(clips: ClipLibrary, final_wait: bool = True, repeat: bool = True) -> PhraseGraph:
    phrases = [
        Phrase("go", "Move your hand away from your body.", None, ("keep", "slow", "done")),
        Phrase("keep", "Keep going.", None, ("done",)),
        Phrase("slow", "Nice and slow, you are doing really well.", None, ("done",)),
        Phrase("done", "And you're done.", None, ()),
    ]
    dur = {p.id: clips.duration(p) for p in phrases}
    reps = [Repeat("enc", ("keep", "slow"), 3, (0.3, 0.6))] if repeat else []
    return PhraseGraph(
        phrases, "go", dur, pause=0.25, voice="natural", repeats=reps, final_wait=final_wait
    )


def test_without_a_repeat_the_last_phrase_is_said_again_and_the_paper_s_end_never(
    clips: ClipLibrary,
) -> None:
    assert _graph(clips).reopen == "keep"  # the shorter of the two first sayings
    assert reopen_vertex(_graph(clips, repeat=False)) == "done#wait"
    assert reopen_vertex(_graph(clips, final_wait=False)) is None


def test_a_pause_line_before_the_last_phrase_and_a_filler_before_it() -> None:
    """A pause line that leads only to the last phrase is its wait: the speech goes on from it;
    with ``{okay|so} Done.`` from the wait straight before the last phrase, not the filler's."""
    paused = [
        Phrase("a", "Go.", None, ("p",)),
        Phrase("p", None, None, ("b",), "pause", (0.2, 1.0)),
        Phrase("b", "Done.", None, ()),
    ]
    assert PhraseGraph(paused, "a", {"a": 1.0, "b": 0.5}, final_wait=True).reopen == "p"
    filled = [
        Phrase("a", "Go.", None, ("f", "b")),
        Phrase("f", "okay", None, ("b",), "filler"),
        Phrase("b", "Done.", None, ()),
    ]
    g = PhraseGraph(filled, "a", {"a": 1.0, "f": 0.3, "b": 0.5}, final_wait=True)
    assert {"f#wait", "b#wait"} <= set(g.phrases) and g.reopen == "b#wait"


def test_the_timeline_goes_on_from_the_vertex_at_the_time_given(clips: ClipLibrary) -> None:
    graph = _graph(clips)
    tl = SpeechTimeline(graph)
    with pytest.raises(ConfigError, match="has not ended"):
        tl.reopen("keep", 0.0)
    while not tl.done:
        tl.step(0.01, 1.0, choice="done#wait", t_x=0.0, pause=0.0)
    end = tl.t_end
    assert end is not None
    with pytest.raises(ConfigError, match="not a vertex"):
        tl.reopen("nope", end + 1.0)
    with pytest.raises(ConfigError, match="t must be >="):
        tl.reopen("keep", end - 1.0)
    said = len(tl.utterances())
    tl.reopen("keep", end + 1.5)
    assert not tl.done and tl.t_end is None and tl.phrase == "keep"
    while not tl.done:
        tl.step(0.01, 1.0, choice="done#wait", t_x=0.0, pause=0.0)
    again = tl.utterances()[said:]
    assert again[0].phrase == "keep" and again[0].t_start == pytest.approx(end + 1.5)
    assert again[-1].phrase == "done" and tl.t_end == again[-1].t_end


def test_a_wait_reopened_is_planned_so_that_the_last_phrase_ends_with_the_motion(
    clips: ClipLibrary,
) -> None:
    graph = _graph(clips, repeat=False)
    tl = SpeechTimeline(graph)
    while not tl.done:
        tl.step(0.01, 1.0, choice="done#wait", t_x=0.0, pause=0.0)
    end = tl.t_end
    assert end is not None
    tl.reopen("done#wait", end + 1.0, t_x=3.0)  # the motion ends 3 s from now
    t_x = 3.0
    while not tl.done:
        tl.step(0.01, 1.0, t_x=t_x)
        t_x -= 0.01
    assert [u.phrase for u in tl.utterances()[-2:]] == ["done#wait", "done"]
    assert tl.t_end == pytest.approx(end + 1.0 + 3.0, abs=0.02)


def _session(
    compiled: bool, exercise: str = "forearm_rotation", seed: int = PUSHED_BACK
) -> tuple[Any, dict[str, np.ndarray], list[Utterance]]:
    policy = make_analytic("lc")
    spoken = speak(policy, exercise, None)
    env: Any = gym.make(
        langenv.ENV_ID,
        phrase_graph=spoken.ref,
        decision_hz=policy.decision_hz,
        exercise=exercise,
        max_episode_steps=60 * policy.decision_hz,
        **policy.env_kwargs,
    ).unwrapped
    if not compiled:
        env._steps = None  # every tick in Python: the reference
    obs, _ = env.reset(seed=seed)
    policy.reset()
    rows: dict[str, list[float]] = {"time": [], "a": [], "p": [], "speech_done": []}
    terminated = False
    while not terminated:
        obs, _, terminated, truncated, info = env.step(policy.act(obs))
        assert not truncated
        for name in rows:
            rows[name].append(float(info[name]))
    return info, {k: np.array(v) for k, v in rows.items()}, env.speech.utterances()


def test_a_person_who_pushes_back_hears_more_words_and_both_end_together() -> None:
    info, rows, said = _session(compiled=True)
    words = [u.phrase for u in said if u.length is None]
    assert words.count("done") == 2  # "And you're done." once more, after "Keep going."
    k = words.index("done")
    assert words[k + 1] == "keep_going_3"
    first_end = next(u.t_end for u in said if u.phrase == "done")
    again = next(u.t_start for u in said if u.phrase == "keep_going_3" and u.t_start > first_end)
    assert again == pytest.approx(first_end + REOPEN_AFTER, abs=0.003)
    assert abs(info["am"]) <= 1.0  # 3.7 s apart before
    went_on = np.flatnonzero(np.diff(rows["speech_done"]) < 0)
    assert went_on.size == 1


def test_the_compiled_ticks_go_on_as_the_python_ones() -> None:
    info_c, rows_c, said_c = _session(compiled=True)
    info_p, rows_p, said_p = _session(compiled=False)
    for name in rows_c:
        np.testing.assert_array_equal(rows_c[name], rows_p[name], err_msg=name)
    assert said_c == said_p
    assert info_c["am"] == info_p["am"]


def test_the_speech_that_goes_on_is_heard_live_and_offline(clips: ClipLibrary) -> None:
    from langenv.live.stream import BLOCK, SpeechStream

    graph = _graph(clips)
    tl, stream = SpeechTimeline(graph), SpeechStream(graph, clips)
    t, dt, trace, live, reopened = 0.0, 0.002, [], [], False
    while t < 20.0 and (not tl.done or not reopened or t < tl.t + 0.5):
        stream.record(t, 1.0, tl.path, tl.done, tl.pause_lengths)
        trace.append(t)
        live.append(stream.render(t, 4 * BLOCK))
        if tl.done and not reopened and tl.t_end is not None and t >= tl.t_end + REOPEN_AFTER:
            tl.reopen("keep", t)
            reopened = True
        if not tl.done:
            tl.step(dt, 1.0, choice="done#wait", t_x=0.0, pause=0.0)
        t += dt
    heard = np.concatenate(live)
    tt = np.asarray(trace)
    offline = render_history(graph, clips, tl.utterances(), tt, np.ones_like(tt))
    restart = next(u for u in tl.utterances() if u.phrase == "keep")
    after = slice(
        round((restart.t_start + 0.1) * clips.sr), round((restart.t_end - 0.1) * clips.sr)
    )
    before = slice(
        round((restart.t_start - 0.8) * clips.sr), round((restart.t_start - 0.1) * clips.sr)
    )
    for audio in (heard, offline):
        assert np.abs(audio[after]).max() > 0.01  # the words that go on are heard
        assert np.abs(audio[before]).max() < 1e-3  # after a silence
    assert stream.starved == 0


def test_a_wait_reopened_in_compiled_ticks_as_in_python_ones() -> None:
    """The new user's plain script (no repeat line): the speech goes on from the last phrase's
    wait, which the compiled ticks then plan as Python does."""
    exercise = str(DATA / "new_user" / "two_leg_reach.yaml")
    info_c, rows_c, said_c = _session(compiled=True, exercise=exercise, seed=PUSHED_BACK_PLAIN)
    info_p, rows_p, said_p = _session(compiled=False, exercise=exercise, seed=PUSHED_BACK_PLAIN)
    for name in rows_c:
        np.testing.assert_array_equal(rows_c[name], rows_p[name], err_msg=name)
    assert said_c == said_p and info_c["am"] == info_p["am"]
    assert [u.phrase for u in said_c].count("done#wait") == 2 and abs(info_c["am"]) <= 1.0


def test_a_batch_goes_on_as_the_single_env() -> None:
    from langenv.batch import LangCtrlVectorEnv

    policy = make_analytic("lc")
    spoken = speak(policy, "forearm_rotation", None)
    kwargs = {"phrase_graph": spoken.ref, "exercise": "forearm_rotation", **policy.env_kwargs}
    venv = LangCtrlVectorEnv(1, decision_hz=policy.decision_hz, **kwargs)
    obs, _ = venv.reset(seed=PUSHED_BACK)
    policy.reset()
    a = []
    while True:
        obs, _, term, trunc, info = venv.step(policy.act(obs[0])[None, :])
        assert not trunc[0]
        a.append(float(info["a"][0]))
        if term[0]:
            break
    venv.close()
    single, rows, _ = _session(compiled=True)
    assert info["am"][0] == single["am"]
    np.testing.assert_array_equal(np.array(a), rows["a"])


def test_the_law_run_in_compiled_code_goes_on_as_the_policy_stepping(tmp_path: Path) -> None:
    """``langctrl compare`` runs LC's pace law in compiled code (``LangCtrlEnv.run_law``): the
    pushed-back person's session ends as the policy stepping the env ends it."""
    import eval.compare as compare

    policy = make_analytic("lc")
    assert policy.decision_hz == 500 and policy.pace_law() is not None  # the run_law path
    job = compare.Job(
        policy="lc", phrase_graph=None, user="s0", seed=PUSHED_BACK, session=None,
        out_dir=str(tmp_path), audio=False, figures=False, decision_hz=None,
        exercise="forearm_rotation", save_log=False,
    )  # fmt: skip
    row = compare.run_episode(job)
    info, _, _ = _session(compiled=True)
    assert float(row["am"]) == info["am"] and abs(info["am"]) <= 1.0
