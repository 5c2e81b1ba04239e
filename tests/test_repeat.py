"""Speech that never runs out: repeats and the last phrase that waits for the motion.

Unrolling (``langenv/speech/repeat.py``), the plans (a repeat said once), the wait's rule, the
compiled ETC on such graphs, the named errors of graph files and scripts.
"""

from __future__ import annotations

import re
from itertools import pairwise
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from langenv.errors import PhraseGraphError, ScriptError
from langenv.speech.audio import ClipLibrary
from langenv.speech.author import parse_script
from langenv.speech.coverage import speech_lengths
from langenv.speech.graph import PhraseGraph
from langenv.speech.phrase import Phrase
from langenv.speech.repeat import MAX_REPEAT, SEP, WAIT_PLAN, Repeat, is_gap
from langenv.speech.timeline import SpeechTimeline
from tests.compiled_graph import c_eta, c_fill


def encourage(
    times: int = 4, gap: tuple[float, float] = (1.0, 2.0), wait: bool = True
) -> PhraseGraph:
    """intro -> [keep | slow] (a repeat) -> done, clips 2, 1, 1.2 and 0.8 s, pause 0.3."""
    phrases = [
        Phrase("intro", "Reach forward.", None, ("keep", "slow", "done")),
        Phrase("keep", "Keep going.", None, ("done",)),
        Phrase("slow", "Nice and slow.", None, ("done",)),
        Phrase("done", "And you're done.", None, ()),
    ]
    dur = {"intro": 2.0, "keep": 1.0, "slow": 1.2, "done": 0.8}
    rep = Repeat("again", ("keep", "slow"), times, gap)
    return PhraseGraph(phrases, "intro", dur, pause=0.3, repeats=[rep], final_wait=wait)


def write(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "g.yaml"
    path.write_text(text, encoding="utf-8")
    return path


# ------------------------------------------------------------------------------ unrolling
def test_a_repeat_unrolls_into_sayings_and_gaps() -> None:
    g = encourage(times=3)
    assert set(g.source_phrases) == {"intro", "keep", "slow", "done"}
    assert g.children("keep") == ("done#wait", "again#gap1")
    assert g.children("again#gap1") == ("keep#2", "slow#2")
    assert g.children("keep#2") == ("done#wait", "again#gap2")
    assert g.children("keep#3") == ("done#wait",)  # the last saying: only the way out
    assert g.slot_range("again#gap2") == (1.0, 2.0)
    assert g.duration["slow#3"] == g.duration["slow"] == 1.2
    assert g.origin("slow#3") == "slow" and g.origin("again#gap1") == "again#gap1"
    assert g.phrases["keep#2"].text == "Keep going."
    assert is_gap("again#gap2") and not is_gap("keep#2") and not is_gap("done#wait")


def test_a_plan_says_a_repeat_once_and_the_coverage_counts_every_saying() -> None:
    g = encourage(times=4)
    assert g.plan_range("done#wait") == (0.0, WAIT_PLAN)
    assert g.slot_range("done#wait")[0] == 0.0
    # intro's plan: intro (2.3) + one saying (1.3 or 1.5) + the planned wait + done (0.8)
    assert g.t_min("intro") == pytest.approx(2.3 + 0.8)  # straight to the end
    assert g.t_max("intro") == pytest.approx(2.3 + 1.5 + WAIT_PLAN + 0.8)
    # the words' longest speech: four sayings of the longer wording with the longest gaps
    longest = 2.3 + 4 * 1.5 + 3 * 2.0 + WAIT_PLAN + 0.8
    assert speech_lengths(g)[-1][1] == pytest.approx(longest)
    # a gap's plan: the gap, one more saying and the end
    assert g.t_min("again#gap1") == pytest.approx(1.0 + 1.3 + 0.8)
    assert g.t_max("again#gap1") == pytest.approx(2.0 + 1.5 + WAIT_PLAN + 0.8)


def test_the_extreme_paths_are_the_plan_s_and_last_t_min_and_t_max() -> None:
    """``longest_path`` had taken every gap (a gap's ``t_max`` counts one more saying), giving a
    path of 16.6 s for a ``t_max`` of 6.1 s."""
    g = encourage(times=4)
    for u in g.order:
        if g.is_terminal(u):
            continue
        assert g.path_range(g.longest_path(u))[1] == pytest.approx(g.t_max(u))
        assert g.path_range(g.shortest_path(u))[0] == pytest.approx(g.t_min(u))


def test_the_rule_says_another_round_when_the_motion_s_time_to_go_is_nearer_it() -> None:
    g = encourage(times=4)
    assert g.choose("keep", 1.0) == "done#wait"
    assert g.choose("keep", 4.0) == "again#gap1"  # one more saying fits better than the end
    assert g.choose("keep#4", 50.0) == "done#wait"  # the bound: nowhere else to go


def test_the_longer_the_motion_the_more_sayings_and_never_more_than_times() -> None:
    g = encourage(times=4)
    said = []
    for motion in (4.0, 8.0, 12.0, 40.0):
        tl = SpeechTimeline(g)
        t = 0.0
        while not tl.done:
            tl.step(0.002, 1.0, t_x=max(0.0, motion - t))
            t += 0.002
        path = [u for u in tl.path if not g.phrases[u].is_pause]
        said.append(sum(g.origin(u) in ("keep", "slow") for u in path))
        assert path[-1] == "done"
    assert said == sorted(said) and said[0] <= 1 and said[-1] == 4


def test_the_last_phrase_starts_when_the_motion_s_time_to_go_is_its_length() -> None:
    g = encourage(times=2)
    tl = SpeechTimeline(g)
    t, motion, start = 0.0, 20.0, None
    while not tl.done:
        tl.step(0.002, 1.0, t_x=max(0.0, motion - t))
        t += 0.002
        if tl.phrase == "done" and start is None:
            start = t
    assert start is not None
    assert motion - start == pytest.approx(0.8, abs=0.005)
    wait = next(u for u in tl.utterances() if u.phrase == "done#wait")
    assert wait.length is not None and wait.length > 5.0  # far past any pause bound


def test_without_final_wait_the_speech_ends_as_the_paper_s_does() -> None:
    g = encourage(times=2, wait=False)
    assert "done#wait" not in g.phrases and not g.opened
    assert g.children("keep") == ("done", "again#gap1")
    tl = SpeechTimeline(g)
    t = 0.0
    while not tl.done:
        tl.step(0.002, 1.0, t_x=max(0.0, 20.0 - t))
        t += 0.002
    assert t < 12.0  # the words run out long before the 20 s motion


def test_a_pause_before_the_last_phrase_becomes_its_wait() -> None:
    phrases = [
        Phrase("a", "Go.", None, ("p",)),
        Phrase("p", None, None, ("b",), "pause", (0.2, 1.0)),
        Phrase("b", "Done.", None, ()),
    ]
    g = PhraseGraph(phrases, "a", {"a": 1.0, "b": 0.5}, final_wait=True)
    assert g.opened == {"p"} and "b#wait" not in g.phrases
    assert g.plan_range("p") == (0.2, 1.0)  # the plan keeps its bounds
    assert g.slot_range("p")[1] > 100.0  # it may last as long as the motion needs
    assert g.pause_length("p", 10.0) == pytest.approx(10.0 - 0.5)


# ------------------------------------------------------------------ random graphs, compiled
@st.composite
def repeat_graphs(draw: st.DrawFn) -> PhraseGraph:
    """A chain of steps with alternatives, one of them a repeat, the last phrase waiting."""
    steps = draw(st.integers(2, 4))
    rep_at = draw(st.integers(1, steps - 1))
    phrases: list[Phrase] = []
    dur: dict[str, float] = {}
    prev: list[str] = []
    for k in range(steps):
        ids = [f"s{k}_{j}" for j in range(1 if k == 0 else draw(st.integers(1, 3)))]
        for p in prev:
            src = next(ph for ph in phrases if ph.id == p)
            phrases[phrases.index(src)] = Phrase(p, src.text, None, tuple(ids))
        for i in ids:
            phrases.append(Phrase(i, f"say {i}", None, ()))
            dur[i] = draw(st.floats(0.2, 3.0))
        if k == rep_at:
            members = tuple(ids)
        prev = ids
    phrases.append(Phrase("end", "Done.", None, ()))
    dur["end"] = draw(st.floats(0.3, 1.5))
    for p in prev:
        src = next(ph for ph in phrases if ph.id == p)
        phrases[phrases.index(src)] = Phrase(p, src.text, None, ("end",))
    lo = draw(st.floats(0.0, 2.0))
    rep = Repeat("r", members, draw(st.integers(2, 5)), (lo, lo + draw(st.floats(0.0, 2.0))))
    return PhraseGraph(phrases, "s0_0", dur, pause=0.3, repeats=[rep], final_wait=True)


@settings(max_examples=60, deadline=None)
@given(repeat_graphs(), st.floats(0.0, 1.0), st.floats(0.0, 60.0))
def test_compiled_eta_equals_the_graph_s_bit_for_bit(
    g: PhraseGraph, frac: float, t_x: float
) -> None:
    order = tuple(g.phrases)
    for i, u in enumerate(order):
        remaining = frac * g.slot(u)
        assert c_eta(g, i, remaining, t_x) == g.eta(u, remaining, t_x)


@settings(max_examples=40, deadline=None)
@given(repeat_graphs())
def test_plans_span_the_paths_that_take_no_further_round(g: PhraseGraph) -> None:
    for u in g.order:
        if g.is_terminal(u):
            continue
        spans = [g.path_range(p) for p in g.paths(u) if not any(is_gap(v) for v in p[1:])]
        assert g.t_min(u) == pytest.approx(min(lo for lo, _ in spans))
        assert g.t_max(u) == pytest.approx(max(hi for _, hi in spans))


@settings(max_examples=40, deadline=None)
@given(repeat_graphs(), st.floats(5.0, 60.0))
def test_the_speech_never_runs_out_before_a_motion_it_can_follow(
    g: PhraseGraph, motion: float
) -> None:
    """At pace 1 with ``t_x`` counting down, the speech never runs out: it ends with the motion
    whenever its shortest speech fits, or later by at most what one choice of the rule can
    overshoot (a step's longest slot; the pace law's job)."""
    if g.t_min(g.start) > motion:
        return
    tl = SpeechTimeline(g)
    t = 0.0
    while not tl.done and t < motion + 60.0:
        tl.step(0.01, 1.0, t_x=max(0.0, motion - t))
        t += 0.01
    assert tl.done and tl.t_end is not None
    longest = max(g.plan_range(u)[1] for u in g.phrases)
    assert motion - 0.02 <= tl.t_end <= motion + longest + 0.02


# ------------------------------------------------------------------ files and their errors
GOOD = """\
start: a
pause: 0.3
final_wait: true
repeats:
  cheer: {phrases: [b, c], times: 3, gap: [1, 2]}
phrases:
  a: {text: "Go.", next: [b, c]}
  b: {text: "Keep going.", next: [d]}
  c: {text: "Nice and slow.", next: [d]}
  d: {text: "Done.", next: []}
"""


def test_a_graph_file_with_a_repeat_and_a_wait_loads(tmp_path: Path, clips: ClipLibrary) -> None:
    g = PhraseGraph.load(write(tmp_path, GOOD), clips)
    assert g.final_wait and set(g.repeats) == {"cheer"}
    assert g.repeats["cheer"].times == 3 and g.repeats["cheer"].gap == (1.0, 2.0)
    assert "c#3" in g.phrases and "d#wait" in g.phrases
    assert g.with_voice("natural").repeats == g.repeats


@pytest.mark.parametrize(
    ("old", "new", "message"),
    [
        ("times: 3, ", "", "a repeat needs a bound: 'times'"),
        ("times: 3", f"times: {MAX_REPEAT + 1}", "'times' must be an integer from 2 to"),
        ("times: 3", "times: 1", "'times' must be an integer from 2 to"),
        ("gap: [1, 2]", "gap: [2, 1]", "bad gap [2, 1]"),
        ("gap: [1, 2]", "gap: [-1, 2]", "bad gap"),
        ("gap: [1, 2]", "gap: [1, 12]", "bad gap"),
        ("gap: [1, 2]", "gap: soon", "'gap' must be seconds"),
        ("[b, c]", "[b, x]", "'x' is not a phrase of this graph"),
        ("[b, c]", "[b, d]", "ends the speech and cannot repeat"),
        ("times: 3", "times: 3, often: yes", "unknown key(s) ['often']"),
        ("[b, c], times", "[a, b], times", "lists 'b' of the same repeat in its next"),
        ("final_wait: true", "final_wait: maybe", "'final_wait' must be true or false"),
    ],
)
def test_bad_repeats_are_named(
    tmp_path: Path, clips: ClipLibrary, old: str, new: str, message: str
) -> None:
    assert old in GOOD
    with pytest.raises(PhraseGraphError, match=r"g\.yaml") as info:
        PhraseGraph.load(write(tmp_path, GOOD.replace(old, new, 1)), clips)
    assert message in str(info.value)


def test_a_repeat_that_can_never_be_left_is_named(tmp_path: Path, clips: ClipLibrary) -> None:
    text = GOOD.replace(
        'b: {text: "Keep going.", next: [d]}', 'b: {text: "Keep going.", next: [c]}'
    )
    text = text.replace('a: {text: "Go.", next: [b, c]}', 'a: {text: "Go.", next: [b]}')
    with pytest.raises(PhraseGraphError, match="can never be left") as info:
        PhraseGraph.load(write(tmp_path, text.replace("[b, c], times", "[b, c], times")), clips)
    assert "repeat 'cheer'" in str(info.value)


def test_ids_with_the_separator_are_refused() -> None:
    with pytest.raises(PhraseGraphError, match=f"may not contain '{re.escape(SEP)}'"):
        PhraseGraph([Phrase("a#1", "Go.", None, ())], "a#1", {"a#1": 1.0})


def test_a_script_line_may_repeat_and_the_graph_says_so(tmp_path: Path) -> None:
    script = parse_script(
        "Go.\nKeep going. | Nice and slow. (repeat 4, gap 1-3)\nDone.\n", tmp_path / "s.txt"
    )
    assert script.final_wait
    (rep,) = script.repeats
    assert (
        rep.times == 4 and rep.gap == (1.0, 3.0) and set(rep.phrases) == {"keep_going", "nice_slow"}
    )
    script = parse_script("@final-wait off\nGo.\n[Keep going.] (repeat 3)\nDone.\n")
    assert not script.final_wait and script.repeats[0].gap == (1.0, 3.0)


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("Go.\nKeep going. (repeat)\nDone.\n", "s.txt:2:13: '(repeat)' is not a repeat"),
        ("Go.\nKeep going. (repeat 1)\nDone.\n", "a line repeats 2 to 20 times"),
        ("Go.\nKeep going. (repeat 3, gap 3-1)\nDone.\n", "bad gap 3-1"),
        ("Go.\nKeep going. (pause 1) (repeat 3)\nDone.\n", "must end with its words"),
        ("@final-wait maybe\nGo.\nDone.\n", "@final-wait takes on or off"),
        ("@loop on\nGo.\nDone.\n", "@final-wait on|off"),
    ],
)
def test_bad_repeats_in_scripts_name_line_and_column(text: str, message: str) -> None:
    with pytest.raises(ScriptError) as info:
        parse_script(text, "s.txt")
    assert message in str(info.value)


def test_the_cli_names_a_bad_repeat_without_a_traceback(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from langctrl.jobs.speech import main

    path = write(tmp_path, GOOD.replace("times: 3, ", ""))
    assert main(["check", str(path), "--cache-dir", str(tmp_path / "c")]) == 1
    err = capsys.readouterr().err
    assert "Traceback" not in err and "g.yaml: repeat 'cheer': a repeat needs a bound" in err


# ------------------------------------------------------- the wait next to pauses and fillers
def _said(g: PhraseGraph, motion: float) -> list[tuple[str, float, float]]:
    tl = SpeechTimeline(g)
    t = 0.0
    while not tl.done:
        tl.step(0.002, 1.0, t_x=max(0.0, motion - t))
        t += 0.002
    return [(u.phrase, u.t_start, u.t_end) for u in tl.utterances()]


def _compiled_agrees(g: PhraseGraph) -> None:
    order = tuple(g.phrases)
    for t_x in (0.0, 2.0, 7.5, 30.0):
        for i, u in enumerate(order):
            remaining = 0.5 * g.slot(u)
            assert c_eta(g, i, remaining, t_x) == g.eta(u, remaining, t_x)


def test_a_pause_that_may_also_lead_elsewhere_keeps_its_bounds() -> None:
    """``(pause) [Almost there.] Done.``: the pause may lead to the optional line or to the last
    phrase. The silence that stretches is the one before the last phrase, not the pause before
    "Almost there." (which had been opened: 14 s of silence, then "Almost there.")."""
    phrases = [
        Phrase("a", "Go.", None, ("q",)),
        Phrase("q", None, None, ("r", "t"), "pause", (0.2, 1.0)),
        Phrase("r", "Almost there.", None, ("t",)),
        Phrase("t", "Done.", None, ()),
    ]
    g = PhraseGraph(phrases, "a", {"a": 1.0, "r": 1.0, "t": 0.5}, pause=0.3, final_wait=True)
    assert "q" not in g.opened and g.slot_range("q") == (0.2, 1.0)
    assert g.children("q") == ("r", "t#wait") and g.children("r") == ("t#wait",)
    said = _said(g, 20.0)
    assert [u for u, *_ in said] == ["a", "q", "r", "t#wait", "t"]
    (q_len,) = [end - start for u, start, end in said if u == "q"]
    assert q_len <= 1.0 + 1e-9
    assert said[-1][2] == pytest.approx(20.0, abs=0.01)
    _compiled_agrees(g)


def test_a_filler_before_the_last_phrase_is_said_after_the_wait() -> None:
    """``{okay|so} And you're done.``: the filler leads into the last phrase; the wait comes
    before it ("Okay." then 15 s of silence then "And you're done." had been the speech)."""
    phrases = [
        Phrase("a", "Go.", None, ("okay", "so", "t")),
        Phrase("okay", "Okay.", None, ("t",), "filler"),
        Phrase("so", "So.", None, ("t",), "filler"),
        Phrase("t", "And you're done.", None, ()),
    ]
    g = PhraseGraph(
        phrases, "a", {"a": 1.0, "okay": 0.5, "so": 0.4, "t": 0.9}, pause=0.3, final_wait=True
    )
    assert g.children("okay") == ("t",) and g.children("a") == ("okay#wait", "so#wait", "t#wait")
    for motion in (6.0, 20.0):
        said = _said(g, motion)
        assert said[-1][0] == "t" and said[-1][2] == pytest.approx(motion, abs=0.01)
        if said[-2][0] in ("okay", "so"):  # the filler, then the clip pause, then the last phrase
            assert said[-1][1] - said[-2][2] == pytest.approx(0.3, abs=0.01)
    _compiled_agrees(g)


def test_a_filler_before_an_optional_line_and_the_last_phrase_is_said_after_the_wait() -> None:
    """``{okay|so} [Almost there.]`` then ``Done.``: the filler leads to the optional line and
    to the last phrase. On its way to the end it is said after the wait, with the last phrase
    ("Okay." then 15 s of silence then "Done." had been the speech); on its way to the optional
    line it is said as before."""
    phrases = [
        Phrase("a", "Go.", None, ("okay", "r")),
        Phrase("okay", "Okay.", None, ("r", "t"), "filler"),
        Phrase("r", "Almost there.", None, ("t",)),
        Phrase("t", "Done.", None, ()),
    ]
    g = PhraseGraph(phrases, "a", {"a": 1.0, "okay": 0.5, "r": 1.0, "t": 0.9}, pause=0.3,
                    final_wait=True)  # fmt: skip
    assert g.children("a") == ("okay", "okay#end#wait", "r")
    assert g.children("okay") == ("r",) and g.children("okay#end") == ("t",)
    assert g.origin("okay#end") == "okay" and g.duration["okay#end"] == 0.5
    for motion in (6.0, 20.0):
        said = _said(g, motion)
        assert said[-1][0] == "t" and said[-1][2] == pytest.approx(motion, abs=0.01)
        for (u, _, end), (v, start, _) in pairwise(said):
            if g.kind(u) == "filler":  # never a wait after a filler: the clip pause only
                assert v in ("r", "t") and start - end == pytest.approx(0.3, abs=0.01)
    _compiled_agrees(g)


def test_members_of_a_repeat_that_lead_to_one_another_are_named(
    tmp_path: Path, clips: ClipLibrary
) -> None:
    """``b -> x -> c`` with ``b`` and ``c`` in one repeat: unrolled, ``c -> gap -> b#2 -> x -> c``
    goes round for ever. It was a bare KeyError from the graph's tables."""
    text = (
        GOOD.replace('b: {text: "Keep going.", next: [d]}', 'b: {text: "Keep going.", next: [x]}')
        + '  x: {text: "And further.", next: [c, d]}\n'
    )
    with pytest.raises(PhraseGraphError, match=r"g\.yaml: repeat 'cheer'") as info:
        PhraseGraph.load(write(tmp_path, text), clips)
    assert "'b' leads to 'c'" in str(info.value)


# ------------------------------------------------ random scripts: the wait and the compiled ETC
_WORDS = ("Go on", "Keep going", "Nice and slow", "Almost there", "Good job", "Lift it")
_ENDINGS = (
    "Done.",
    "{okay|good} Done.",
    "Done. | All done.",
    "[Nearly.]\nDone.",
    "{okay|good} [Nearly.]\nDone.",
)


@st.composite
def script_graphs(draw: st.DrawFn) -> PhraseGraph:
    """The graph of a random script (steps with alternatives, optional lines, pauses, fillers,
    repeats, endings with fillers or optional lines before them), clips of random lengths."""
    lines = ["Start here."]
    for i in range(draw(st.integers(1, 5))):
        kind = draw(st.sampled_from(["plain", "optional", "pause", "filler", "repeat"]))
        alts = [f"{draw(st.sampled_from(_WORDS))} {i}{j}." for j in range(draw(st.integers(1, 3)))]
        if kind == "optional" or (kind == "repeat" and draw(st.booleans())):
            alts = [f"[{a}]" for a in alts]
        line = " | ".join(alts)
        if kind == "pause":
            line = f"(pause {draw(st.sampled_from(['0.2-1', '0-2', '0.5']))})"
        elif kind == "filler":
            line = "{okay|so} " + line
        elif kind == "repeat":
            line += f" (repeat {draw(st.integers(2, 4))}, gap 0.3-1)"
        lines.append(line)
    lines.append(draw(st.sampled_from(_ENDINGS)))
    try:
        script = parse_script("\n".join(lines) + "\n")
    except ScriptError:  # two pauses that can follow each other: refused, rightly
        return draw(repeat_graphs())
    lengths = st.floats(0.4, 3.0)
    dur = {
        v.id: draw(st.floats(0.2, 0.5) if v.kind == "filler" else lengths)
        for v in script.vertices.values()
        if v.kind != "pause"
    }
    phrases = [
        Phrase(v.id, v.text, None, tuple(v.next), v.kind, v.bounds)
        for v in script.vertices.values()
    ]
    reps = [Repeat(r.name, r.phrases, r.times, r.gap) for r in script.repeats]
    return PhraseGraph(phrases, script.start, dur, pause=0.25, repeats=reps, final_wait=True)


@settings(max_examples=60, deadline=None)
@given(script_graphs(), st.floats(3.0, 60.0))
def test_only_the_silence_before_the_ending_words_outlasts_its_plan(
    g: PhraseGraph, motion: float
) -> None:
    """On any script's graph: the compiled ETC and pause rule equal the graph's bit for bit; an
    opened pause leads only to words that end the speech; at pace 1 a pause outlasts its
    planned maximum only when nothing but the ending words (fillers, the last phrase) follows,
    and never right after a filler. Fails before the wait went before the ending words (a pause
    before an optional line was opened; a filler was followed by the wait)."""
    order = tuple(g.phrases)
    for i, u in enumerate(order):
        for t_x in (0.0, motion / 3, motion):
            remaining = 0.3 * g.slot(u)
            assert c_eta(g, i, remaining, t_x) == g.eta(u, remaining, t_x)
            if u in g.pauses:
                assert c_fill(g, i, t_x) == g.pause_length(u, t_x)
    for u in g.opened:
        assert all(g.kind(v) != "pause" for v in g.children(u))
    if g.t_min(g.start) > motion:
        return
    tl = SpeechTimeline(g)
    t = 0.0
    while not tl.done and t < motion + 60.0:
        tl.step(0.01, 1.0, t_x=max(0.0, motion - t))
        t += 0.01
    assert tl.done
    said = list(tl.utterances())
    for k, utt in enumerate(said):
        if utt.length is not None and utt.length > g.plan_range(utt.phrase)[1] + 1e-6:
            after = [w.phrase for w in said[k + 1 :] if w.phrase not in g.pauses]
            assert all(g.kind(w) == "filler" or g.is_terminal(w) for w in after), (utt, after)
            # a filler leads into its phrase: never followed by the long silence (the fillers
            # of these scripts lead into one step's words)
            assert k == 0 or g.kind(said[k - 1].phrase) != "filler", (said[k - 1], utt)
