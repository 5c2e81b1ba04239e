"""Words with intents: ``<INTENT>`` in scripts, ``intent:`` in the YAML, ``PhraseGraph.intent``."""

from __future__ import annotations

import re
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from langenv.errors import PhraseGraphError, ScriptError
from langenv.exercise.registry import SHIPPED_EXERCISES
from langenv.speech.audio import ClipLibrary
from langenv.speech.author import graph_yaml, parse_script
from langenv.speech.graph import GRAPHS_DIR, PhraseGraph
from langenv.speech.intents import INTENTS, intent_problem
from langenv.speech.phrase import Phrase
from langenv.speech.repeat import Repeat
from langenv.speech.variant import GraphVariation, vary_graph

SCRIPT = """\
@pause 0.25
Move your hand away.<guide>
(pause 0.2-0.8)
[Keep going.]<encourage> | [Relax your arm.]<relax> | Slide. (repeat 3, gap 0.3-1)
{okay|so} Bring it back. <guide> (pause 0.5) [Good,] and done.<encourage>
"""


def test_the_vocabulary_has_the_intents_the_issue_names() -> None:
    assert {"guide", "encourage", "relax", "faster", "slower"} <= set(INTENTS)
    assert intent_problem("relax") == ""
    assert "unknown intent 'calm'" in intent_problem("calm")
    assert "guide" in intent_problem("calm")  # lists the known ones


def test_a_mark_goes_to_the_wordings_it_follows_and_into_the_yaml() -> None:
    s = parse_script(SCRIPT, "s.txt")
    v = s.vertices
    assert v["move_hand_away"].intent == "guide"
    assert v["keep_going"].intent == "encourage" and v["relax_arm"].intent == "relax"
    assert v["slide"].intent is None  # unmarked
    assert v["okay"].intent is None and v["pause_3"].intent is None
    assert v["bring_it_back"].intent == "guide"
    # both wordings of "[Good,] and done." carry the mark
    assert v["good_done"].intent == v["done"].intent == "encourage"
    text = graph_yaml(s, "s.txt")
    block = text.split("  keep_going:")[1].splitlines()[1:4]
    assert block == [
        '    text: "Keep going."',
        "    intent: encourage",
        "    next: [okay, so, bring_it_back]",
    ]
    assert text.count("intent:") == 6


def _without_intent_lines(text: str) -> str:
    return "".join(line for line in text.splitlines(keepends=True) if "    intent: " not in line)


def test_an_unmarked_script_writes_the_same_bytes_as_before() -> None:
    unmarked = re.sub(r"\s*<\w+>", "", SCRIPT)
    assert "<" not in unmarked
    text = graph_yaml(parse_script(unmarked, "s.txt"), "s.txt")
    assert "intent" not in text
    assert _without_intent_lines(graph_yaml(parse_script(SCRIPT, "s.txt"), "s.txt")) == text


WORDINGS = ("Keep going.", "Nice and slow.", "Relax your arm.", "Up, up, up.", "One more.")


@settings(max_examples=60, deadline=None)
@given(
    st.lists(
        st.lists(
            st.tuples(
                st.sampled_from(WORDINGS),
                st.booleans(),
                st.one_of(st.none(), st.sampled_from(sorted(INTENTS))),
            ),
            min_size=1,
            max_size=3,
            unique_by=lambda x: x[0],
        ),
        min_size=1,
        max_size=4,
    )
)
def test_marks_add_intent_lines_and_change_nothing_else(lines: list) -> None:
    def script(marked: bool) -> str:
        out = ["Go now."]
        for alts in lines:
            words = []
            for text, optional, intent in alts:
                w = f"[{text}]" if optional else text
                words.append(w + (f"<{intent}>" if marked and intent else ""))
            out.append(" | ".join(words))
        out.append("And done.")
        return "\n".join(out) + "\n"

    marked = parse_script(script(True), "p.txt")
    plain = graph_yaml(parse_script(script(False), "p.txt"), "p.txt")
    assert _without_intent_lines(graph_yaml(marked, "p.txt")) == plain
    for vid, v in marked.vertices.items():  # each wording carries its own line's mark
        if v.kind == "phrase" and v.line > 1 and v.text != "And done.":
            alts = lines[v.line - 2]
            expected = {i for t, _, i in alts if t == v.text}
            assert {v.intent} == expected, vid


BAD = {
    "unknown": ("Go.\n[Keep going.]<encourag>\n", "s.txt:2:15: unknown intent 'encourag'"),
    "empty": ("Go.\nKeep going.<>\n", "s.txt:2:12: empty '<>'"),
    "before the words": ("Go.\n<guide> Keep going.\n", "s.txt:2:1: an intent follows"),
    "after a pause": ("Go.\nA. (pause 1)<guide>\nB.\n", "s.txt:2:13: an intent follows"),
    "words after it": (
        "Go.\nKeep<guide> going.\n",
        "s.txt:2:13: words after the intent of column 5",
    ),
    "optional words after it": ("Go.\nKeep<guide> [going.]\n", "s.txt:2:13: words after"),
    "two": ("Go.\nKeep going.<guide><relax>\n", "s.txt:2:19: a wording carries one intent"),
    "inside brackets": ("Go.\n[Keep <guide>]\n", "s.txt:2:7: '<' inside '['"),
    "not closed": ("Go.\nKeep going.<guide\n", "s.txt:2:12: '<' is not closed"),
    "a stray close": ("Go.\nKeep going.>\n", "s.txt:2:12: '>' closes nothing"),
}


@pytest.mark.parametrize("case", sorted(BAD))
def test_a_bad_mark_is_a_script_error_at_its_line_and_column(case: str) -> None:
    source, message = BAD[case]
    with pytest.raises(ScriptError) as err:
        parse_script(source, "s.txt")
    assert str(err.value).startswith(message), str(err.value)


def _graph(intents: dict[str, str]) -> PhraseGraph:
    phrases = [
        Phrase("go", "Go.", None, ("pause",)),
        Phrase("pause", None, None, ("keep", "okay"), "pause", (0.2, 0.8)),
        Phrase("okay", "Okay", None, ("keep",), "filler"),
        Phrase("keep", "Keep going.", None, ("done",)),
        Phrase("done", "Done.", None, ()),
    ]
    durations = {"go": 0.5, "okay": 0.3, "keep": 0.7, "done": 0.5}
    return PhraseGraph(
        phrases,
        "go",
        durations,
        repeats=[Repeat("again", ("keep",), 3, (0.3, 1.0))],
        final_wait=True,
        intents=intents,
    )


def test_unrolled_vertices_inherit_their_wordings_intent() -> None:
    g = _graph({"keep": "encourage", "go": "guide"})
    assert g.intent("go") == "guide"
    copies = [u for u in g.phrases if u.startswith("keep")]
    assert len(copies) == 3 and {g.intent(u) for u in copies} == {"encourage"}
    assert g.intent("done") is None and g.intent("okay") is None
    assert all(g.intent(u) is None for u in g.pauses)  # pauses, gaps, the wait
    assert g.with_voice("natural").intent("keep#2") == "encourage"
    with pytest.raises(PhraseGraphError, match="no phrase 'nope'"):
        g.intent("nope")


def test_a_variant_keeps_the_intents_of_its_wordings() -> None:
    import numpy as np

    g = _graph({"keep": "encourage", "go": "guide"})
    for seed in range(5):
        v = vary_graph(g, np.random.default_rng(seed), GraphVariation(p_add=1.0))
        for u in v.phrases:
            if v.kind(u) == "phrase":
                assert v.intent(u) == g.intent_of.get(v.origin(u).split("~")[0]), u


@pytest.mark.parametrize(
    ("intents", "message"),
    [
        ({"pause": "relax"}, "pause 'pause': only a phrase carries an intent"),
        ({"okay": "encourage"}, "filler 'okay': only a phrase carries an intent"),
        ({"keep": "calm"}, "phrase 'keep': unknown intent 'calm'"),
        ({"gone": "guide"}, "intent of 'gone': the graph has no such vertex"),
    ],
)
def test_a_graph_refuses_a_bad_intent(intents: dict[str, str], message: str) -> None:
    with pytest.raises(PhraseGraphError, match=re.escape(message)):
        _graph(intents)


YAML = """\
start: go
phrases:
  go: {text: "Go.", next: [pause]}
  pause: {pause: [0.2, 0.8], next: [keep]}
  keep: {text: "Keep going.", intent: %s, next: []}
"""


def test_the_yaml_names_the_file_and_vertex_of_an_unknown_intent(
    tmp_path: Path, clips: ClipLibrary
) -> None:
    path = tmp_path / "g.yaml"
    path.write_text(YAML % "encourage")
    assert PhraseGraph.load(path, clips).intent("keep") == "encourage"
    path.write_text(YAML % "cheer")
    with pytest.raises(PhraseGraphError) as err:
        PhraseGraph.load(path, clips)
    assert str(err.value) == (
        f"{path}: vertex 'keep': unknown intent 'cheer'; known: {', '.join(INTENTS)}"
    )
    path.write_text(
        YAML.replace("pause: [0.2, 0.8],", "pause: [0.2, 0.8], intent: relax,") % "guide"
    )
    with pytest.raises(PhraseGraphError, match=re.escape(f"{path}: pause 'pause': only a phrase")):
        PhraseGraph.load(path, clips)


_SCRIPTS_DIR = Path(SHIPPED_EXERCISES["hand_to_mouth"]).parent / "scripts"
SHIPPED_SCRIPTS = [GRAPHS_DIR / "default.txt", *sorted(_SCRIPTS_DIR.glob("*_lc.txt"))]


@pytest.mark.parametrize("script", SHIPPED_SCRIPTS, ids=lambda p: p.stem)
def test_shipped_scripts_offer_intents_where_a_therapist_would(script: Path) -> None:
    s = parse_script(script.read_text(), script)
    by_text = {v.text: v.intent for v in s.vertices.values() if v.kind == "phrase"}
    assert by_text["Keep going."] == "encourage"
    assert by_text["You're doing really well."] == "encourage"
    assert by_text["Nice and slow."] == "slower"
    assert by_text["Try to relax those fingers, alright."] == "relax"
    assert by_text["And you're done."] is None
    # some step offers wordings with different intents to choose from
    lines: dict[int, set[str | None]] = {}
    for v in s.vertices.values():
        if v.kind == "phrase":
            lines.setdefault(v.line, set()).add(v.intent)
    assert sum(len(i - {None}) >= 2 for i in lines.values()) >= 5
    assert _without_intent_lines(script.with_suffix(".yaml").read_text()) == graph_yaml(
        parse_script(re.sub(r"<\w+>", "", script.read_text()), script), script.name
    )
