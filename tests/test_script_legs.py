"""Scripts say which leg each line speaks about: ``@leg`` marks, their named errors, the graph's
legs (YAML, unrolled vertices), the per-leg words and the warnings against an exercise."""

from __future__ import annotations

from pathlib import Path

import pytest

from langctrl.jobs.exercise import main as exercise_main
from langctrl.jobs.speech import main as speech_main
from langenv.errors import PhraseGraphError, ScriptError
from langenv.exercise import resolve_exercise
from langenv.exercise.check import leg_problems
from langenv.script_fit import MotionTimes, leg_fit_warnings, leg_warnings
from langenv.speech.audio import ClipLibrary
from langenv.speech.author import author, graph_yaml, parse_script
from langenv.speech.coverage import leg_lengths
from langenv.speech.graph import GRAPHS_DIR, PhraseGraph
from langenv.speech.phrase import Phrase

LEGS = ("out", "back", "again")
MARKED = """\
@pause 0.5
@leg out
Move your hand away from your body.
[Glide really smoothly.]
@leg back
(pause 0.5-2)
{okay|so} And back to the middle.
@leg again
One more.
[Keep going.] | [Nice and slow.] (repeat 3, gap 1-2)
And you're done.
"""


@pytest.fixture(autouse=True)
def tts_cache(tmp_path_factory: pytest.TempPathFactory, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("LANGCTRL_CACHE", str(tmp_path_factory.getbasetemp() / "tts-cache"))


def test_each_line_belongs_to_the_leg_marked_above_it() -> None:
    s = parse_script(MARKED, "s.txt", LEGS)
    assert s.legs == LEGS and s.marks == {"out": (2, 6), "back": (5, 6), "again": (8, 6)}
    legs = {v.id: v.leg for v in s.vertices.values()}
    assert legs["move_hand_away"] == legs["glide_really_smoothly"] == "out"
    assert legs["pause_6"] == "back"  # a pause right after a mark is that leg's
    assert legs["okay"] == legs["so"] == legs["back_middle"] == "back"
    assert legs["one_more"] == legs["keep_going"] == legs["done"] == "again"
    text = graph_yaml(s, "s.txt")
    assert "legs: [out, back, again]" in text
    assert text.count("    leg: ") == len(s.vertices)


def test_an_unmarked_script_writes_the_yaml_it_wrote_before() -> None:
    """The marks add the keys ``legs`` and ``leg`` and nothing else (the same lines, read as
    comments, give the unmarked graph)."""
    unmarked = MARKED.replace("@leg", "# @leg")
    plain = graph_yaml(parse_script(unmarked, "s.txt"), "s.txt")
    assert "legs:" not in plain and "    leg: " not in plain
    marked = graph_yaml(parse_script(MARKED, "s.txt"), "s.txt").splitlines()
    kept = [ln for ln in marked if not ln.startswith(("legs:", "    leg: "))]
    assert kept == plain.splitlines()


BAD_MARKS = {
    "unknown leg": (
        MARKED.replace("@leg back", "@leg bakc"),
        "s.txt:5:6: 'bakc' is not a leg of the exercise; its legs: out, back, again",
    ),
    "marked twice": (
        MARKED.replace("@leg again", "@leg back"),
        "s.txt:8:6: leg 'back' is marked twice (first on line 5)",
    ),
    "out of order": (
        MARKED.replace("@leg back", "@leg tmp")
        .replace("@leg again", "@leg back")
        .replace("@leg tmp", "@leg again"),
        "s.txt:8:6: leg 'back' is marked after 'again', which the exercise does later",
    ),
    "mark inside a line": (
        MARKED.replace("One more.", "One more. @leg again"),
        "s.txt:9:11: a @leg mark stands on its own line",
    ),
    "a line before the first mark": (
        MARKED.replace("@pause 0.5\n", "@pause 0.5\nHello there.\n"),
        "s.txt:2:1: this step comes before the first @leg mark (line 3)",
    ),
    "no name": (MARKED.replace("@leg out", "@leg"), "s.txt:2:1: @leg takes one leg name"),
    "two names": (MARKED.replace("@leg out", "@leg out back"), "s.txt:2:1: @leg takes one"),
}


@pytest.mark.parametrize("case", sorted(BAD_MARKS))
def test_bad_marks_are_named_errors_with_file_line_and_column(case: str) -> None:
    source, message = BAD_MARKS[case]
    with pytest.raises(ScriptError) as err:
        parse_script(source, "s.txt", LEGS)
    assert str(err.value).startswith(message), str(err.value)


def test_without_an_exercise_any_names_in_any_order_are_taken() -> None:
    s = parse_script(MARKED.replace("@leg back", "@leg zzz"), "s.txt")
    assert s.legs == ("out", "zzz", "again")


def _graph(legs: tuple[str, ...] = LEGS, leg_of: dict[str, str] | None = None) -> PhraseGraph:
    """go (out, 2 s) > [pause] > back (back, 1 s) | {so} back > more (again, 1.5 s, repeat 2) >
    done (again, 1 s); the last phrase waits for the motion."""
    from langenv.speech.repeat import Repeat

    phrases = [
        Phrase("go", "Go.", None, ("p", "so", "back")),
        Phrase("p", None, None, ("so", "back"), kind="pause", bounds=(0.5, 1.0)),
        Phrase("so", "So", None, ("back",), kind="filler"),
        Phrase("back", "Back.", None, ("more",)),
        Phrase("more", "More.", None, ("done",)),
        Phrase("done", "Done.", None, ()),
    ]
    own = {"go": "out", "p": "back", "so": "back", "back": "back", "more": "again"}
    own["done"] = "again"
    dur = {"go": 2.0, "so": 0.5, "back": 1.0, "more": 1.5, "done": 1.0}
    return PhraseGraph(
        phrases,
        "go",
        dur,
        pause=0.25,
        repeats=[Repeat("again", ("more",), 2, (1.0, 1.0))],
        final_wait=True,
        legs=legs,
        leg_of=own if leg_of is None else leg_of,
    )


def test_unrolled_vertices_take_the_leg_of_what_they_say() -> None:
    g = _graph()
    assert g.legs == LEGS
    # a pause at the start of a leg's lines is the silence before them: the leg before's
    assert {u: g.leg(u) for u in ("go", "p", "so", "back", "more")} == {
        "go": "out", "p": "out", "so": "back", "back": "back", "more": "again"
    }  # fmt: skip
    assert all(g.leg(u) == "again" for u in ("more#2", "again#gap1", "done#wait"))
    with pytest.raises(PhraseGraphError, match="no phrase 'nowhere'"):
        g.leg("nowhere")


def test_an_unmarked_graph_has_no_legs() -> None:
    g = _graph(legs=(), leg_of={})
    assert g.legs == () and all(g.leg(u) is None for u in g.phrases)


@pytest.mark.parametrize(
    ("legs", "leg_of", "message"),
    [
        (LEGS, {"go": "out"}, "phrase 'back': no 'leg'"),
        (LEGS, {"go": "sideways"}, "phrase 'go': leg 'sideways' is not one of"),
        ((), {"go": "out"}, "have a 'leg' but the graph lists no 'legs'"),
        (("out", "out"), {}, "'legs' must be distinct leg names"),
    ],
)
def test_bad_legs_of_a_graph_are_named(
    legs: tuple[str, ...], leg_of: dict[str, str], message: str
) -> None:
    with pytest.raises(PhraseGraphError, match=message.replace("[", r"\[").replace("(", r"\(")):
        _graph(legs, leg_of)


def test_a_graph_file_reads_its_legs_back(tmp_path: Path, clips: ClipLibrary) -> None:
    (tmp_path / "s.txt").write_text(MARKED)
    g = author(tmp_path / "s.txt", tmp_path / "s.yaml", clips, LEGS)
    again = PhraseGraph.load(tmp_path / "s.yaml", clips)
    assert again.legs == g.legs == LEGS
    assert {u: again.leg(u) for u in again.phrases} == {u: g.leg(u) for u in g.phrases}
    assert again.with_voice("natural").leg("back_middle") == "back"
    bad = (tmp_path / "s.yaml").read_text().replace("    leg: back\n", "    leg: 7\n", 1)
    (tmp_path / "bad.yaml").write_text(bad)
    with pytest.raises(PhraseGraphError, match="'leg' must be a leg name, got 7"):
        PhraseGraph.load(tmp_path / "bad.yaml", clips)


def test_a_leg_s_words_are_its_vertices_slots() -> None:
    g = _graph()
    # out: go's slot (2 + 0.25), then its pause (0.5-1) or the gate before back's words (a
    # wait planned as 0-1.5 s, langenv.speech.legs)
    assert leg_lengths(g, "out") == ((2.25, 3.75),)
    # back: [so 0.75] back 1.25, then the gate before again's words (0-1.5)
    assert leg_lengths(g, "back") == ((1.25, 3.5),)
    # again: more (1.75), or more, the gap (1) and more again, then a wait (0-1.5) and done (1)
    assert leg_lengths(g, "again") == ((2.75, 4.25), (5.5, 7.0))
    assert leg_lengths(g, "nowhere") == ((0.0, 0.0),)


def _times(nominal: float, lo: float, hi: float) -> MotionTimes:
    return MotionTimes(nominal, tuple(lo + (hi - lo) * k / 47 for k in range(48)))


def test_a_leg_whose_words_are_too_long_or_too_short_is_warned_about() -> None:
    long = leg_fit_warnings("g.yaml", "out", ((3.3, 3.3),), _times(2.5, 3.0, 6.0), False)
    assert len(long) == 2 and long[0].startswith("warning: g.yaml: leg 'out': its words need")
    assert "2.5 s at cooperation 1" in long[0] and "into the next leg" in long[0]
    assert "the slowest 5 % of 48 people" in long[1] and "(repeat " in long[1]
    end = leg_fit_warnings("g.yaml", "again", ((9.0, 9.0),), _times(6.0, 7.0, 9.0), True)
    assert len(end) == 1 and "past the motion's end" in end[0]
    assert leg_fit_warnings("g.yaml", "back", ((3.0, 8.0),), _times(3.5, 3.5, 6.0), False) == []


def test_legs_without_words_and_unmarked_graphs_are_warned_about() -> None:
    ex = resolve_exercise("external_rotation")
    times = MotionTimes(10.0, (10.0,) * 48)  # no per-leg times: the fit is not checked
    unmarked = leg_warnings(_graph(legs=(), leg_of={}), ex, times)
    assert len(unmarked) == 1 and "no @leg marks" in unmarked[0]
    assert "out, back, again" in unmarked[0]
    silent = {u: "out" for u in ("go", "p", "so", "back", "more", "done")}
    found = leg_warnings(_graph(leg_of=silent), ex, times)
    assert [w.split(": ")[2].split(" of ")[0] for w in found] == ["leg 'back'", "leg 'again'"]
    assert all("has no words" in w for w in found)


def test_speech_author_refuses_a_leg_the_exercise_lacks(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    script = tmp_path / "s.txt"
    script.write_text(MARKED.replace("@leg back", "@leg sideways"))
    out = tmp_path / "g.yaml"
    args = ["author", str(script), "--out", str(out), "--cache-dir", str(tmp_path / "c")]
    assert speech_main([*args, "--exercise", "external_rotation"]) == 1
    err = capsys.readouterr().err
    assert f"{script}:5:6: 'sideways' is not a leg of the exercise" in err and not out.exists()


def test_speech_author_without_an_exercise_warns_about_an_unmarked_script(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    script = tmp_path / "s.txt"
    script.write_text(MARKED.replace("@leg", "# @leg"))
    args = ["author", str(script), "--out", str(tmp_path / "g.yaml")]
    assert speech_main([*args, "--cache-dir", str(tmp_path / "c")]) == 0
    assert "warning: g.yaml: no @leg marks" in capsys.readouterr().out
    script.write_text(MARKED)
    assert speech_main([*args, "--overwrite", "--cache-dir", str(tmp_path / "c")]) == 0
    assert "warning:" not in capsys.readouterr().out


def test_exercise_check_refuses_a_graph_with_a_leg_the_exercise_lacks(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    text = (GRAPHS_DIR / "default.yaml").read_text()
    assert text.count("legs: [out, back, again]") == 1
    bad = text.replace("legs: [out, back, again]", "legs: [out, bak, again]")
    (tmp_path / "g.yaml").write_text(bad.replace("leg: back", "leg: bak"))
    source = Path(resolve_exercise("external_rotation").path or "").read_text()
    exercise = tmp_path / "ex.yaml"
    exercise.write_text(source.replace("graph: default", f"graph: {tmp_path / 'g.yaml'}"))
    assert exercise_main(["check", str(exercise)]) == 1
    err = capsys.readouterr().err
    line = 1 + text.splitlines().index("legs: [out, back, again]   # the exercise's legs the "
                                      "lines speak about")  # fmt: skip
    assert f"{tmp_path / 'g.yaml'}:{line}:13: 'bak' is not a leg of the exercise" in err


def test_leg_problems_name_the_order_too(tmp_path: Path) -> None:
    path = tmp_path / "g.yaml"
    path.write_text("legs: [back, out]\n")
    found = leg_problems(("back", "out"), LEGS, path)
    assert found == [
        ("out", f"{path}:1:14", "leg 'out' comes after a later leg; legs follow the exercise's "
         "order (out, back, again)"),
    ]  # fmt: skip
    assert leg_problems(LEGS, LEGS, path) == [] and leg_problems((), LEGS, path) == []


@pytest.mark.parametrize(
    "path",
    [GRAPHS_DIR / "default.yaml", *sorted(GRAPHS_DIR.parent.glob("exercises/scripts/*_lc.yaml"))],
)
def test_every_shipped_script_is_marked_with_its_exercise_s_legs(path: Path) -> None:
    g = PhraseGraph.load(path)
    name = "external_rotation" if path.stem == "default" else path.stem.removesuffix("_lc")
    assert g.legs == resolve_exercise(name).leg_names
    assert all(g.leg(u) in g.legs for u in g.phrases)


@pytest.mark.parametrize(
    "path",
    [
        GRAPHS_DIR / "study.yaml",
        GRAPHS_DIR / "lc_noap.yaml",
        *sorted(GRAPHS_DIR.parent.glob("exercises/scripts/*_single.yaml")),
    ],
)
def test_the_study_s_graphs_and_the_single_wordings_stay_unmarked(path: Path) -> None:
    assert "leg" not in path.read_text() and PhraseGraph.load(path).legs == ()
