"""Pauses and fillers in phrase graphs: t_min/t_max, the pause rule, compiled ETC, validation."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from langenv.errors import PhraseGraphError
from langenv.speech.audio import ClipLibrary
from langenv.speech.coverage import coverage, speech_lengths
from langenv.speech.graph import PhraseGraph, default_graph_path
from langenv.speech.phrase import MAX_FILLER, Phrase
from tests.compiled_graph import c_eta


def write(tmp_path: Path, text: str, name: str = "g.yaml") -> Path:
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    return path


# ---------------------------------------------------------------- random DAGs with pauses
@st.composite
def pause_dags(draw: st.DrawFn) -> PhraseGraph:
    """A random layered DAG of phrases, fillers and pauses that passes validation."""
    n = draw(st.integers(2, 9))
    kinds = ["phrase"] + [
        draw(st.sampled_from(["phrase", "phrase", "filler", "pause"])) for _ in range(n - 1)
    ]
    kinds[-1] = "phrase"
    nxt: list[list[int]] = []
    for i in range(n):
        later = list(range(i + 1, n))
        if not later:
            nxt.append([])
            continue
        kids = draw(st.lists(st.sampled_from(later), unique=True, min_size=1, max_size=3))
        if kinds[i] == "pause":
            kids = [k for k in kids if kinds[k] != "pause"] or [n - 1]
        nxt.append(sorted(kids))
    # every vertex reachable from 0 is enough (unreachable ones are allowed in memory)
    phrases = []
    dur = {}
    for i, kind in enumerate(kinds):
        pid = f"v{i}"
        kids = tuple(f"v{k}" for k in nxt[i])
        if kind == "pause":
            lo = draw(st.floats(0.0, 2.0))
            hi = lo + draw(st.floats(0.0, 2.0))
            phrases.append(Phrase(pid, None, None, kids, "pause", (lo, hi)))
        else:
            phrases.append(Phrase(pid, f"say {i}", None, kids, kind))
            dur[pid] = draw(st.floats(0.1, MAX_FILLER if kind == "filler" else 4.0))
    pause = draw(st.sampled_from([0.0, 0.3, 1.0]))
    return PhraseGraph(phrases, "v0", dur, pause=pause)


def brute_lengths(g: PhraseGraph, u: str) -> list[tuple[float, float]]:
    out = []
    for path in g.paths(u):
        out.append(g.path_range(path))
    return out


@settings(max_examples=60, deadline=None)
@given(pause_dags())
def test_t_min_t_max_span_every_path_with_pauses_at_their_bounds(g: PhraseGraph) -> None:
    for u in g.order:
        if g.is_terminal(u):
            continue
        spans = brute_lengths(g, u)
        assert g.t_min(u) == pytest.approx(min(lo for lo, _ in spans))
        assert g.t_max(u) == pytest.approx(max(hi for _, hi in spans))


@settings(max_examples=60, deadline=None)
@given(pause_dags(), st.floats(0.0, 30.0))
def test_pause_length_stays_in_bounds_and_meets_the_target_when_it_can(
    g: PhraseGraph, target: float
) -> None:
    for v in g.pauses:
        lo, hi = g.slot_range(v)
        length = g.pause_length(v, target)
        assert lo <= length <= hi
        # inside its bounds the pause fills exactly what the rest of the speech (planned with
        # the pause at its middle length) leaves of the target
        expected = target - _nominal_rest(g, v, target)
        if lo < expected < hi:
            assert length == pytest.approx(expected)
        else:
            assert length == (lo if expected <= lo else hi)


def _nominal_rest(g: PhraseGraph, v: str, target: float) -> float:
    """Speech after pause ``v`` as the rule takes it with the pause at its middle length."""
    left = target - g.slot(v)
    total = 0.0
    kids = g.children(v)
    while kids:
        w = _choose(g, kids, left)
        total += g.slot(w)
        left -= g.slot(w)
        kids = g.children(w)
    return total


def _choose(g: PhraseGraph, kids: tuple[str, ...], left: float) -> str:
    best = kids[0]
    for w in kids[1:]:
        if abs(left - 0.5 * (g.t_min(w) + g.t_max(w))) < abs(
            left - 0.5 * (g.t_min(best) + g.t_max(best))
        ):
            best = w
    return best


@settings(max_examples=60, deadline=None)
@given(pause_dags(), st.floats(0.0, 1.0), st.floats(0.0, 30.0))
def test_compiled_eta_equals_the_graph_s_bit_for_bit(
    g: PhraseGraph, frac: float, t_x: float
) -> None:
    order = tuple(g.phrases)
    for i, u in enumerate(order):
        remaining = frac * g.slot(u)
        assert c_eta(g, i, remaining, t_x) == g.eta(u, remaining, t_x)


@settings(max_examples=40, deadline=None)
@given(pause_dags())
def test_coverage_is_the_union_of_every_path_s_range(g: PhraseGraph) -> None:
    spans = sorted(brute_lengths(g, g.start))
    got = speech_lengths(g)
    for lo, hi in spans:  # every path's range lies inside one merged interval
        assert any(a - 1e-9 <= lo and hi <= b + 1e-9 for a, b in got)
    for a, b in got:  # and every merged interval is covered by paths' ranges
        assert any(abs(a - lo) < 1e-9 for lo, _ in spans)
        assert any(abs(b - hi) < 1e-9 for _, hi in spans)


# ---------------------------------------------------------------- a small graph by hand
def small(pause: float = 0.5) -> PhraseGraph:
    phrases = [
        Phrase("a", "Go.", None, ("wait",)),
        Phrase("wait", None, None, ("okay", "b"), "pause", (0.5, 2.0)),
        Phrase("okay", "Okay.", None, ("b",), "filler"),
        Phrase("b", "And you're done.", None, ()),
    ]
    return PhraseGraph(phrases, "a", {"a": 1.0, "okay": 0.5, "b": 1.0}, pause=pause)


def test_a_pause_adds_its_bounds_to_t_min_and_t_max() -> None:
    g = small()
    assert g.slot_range("wait") == (0.5, 2.0)
    assert g.slot("wait") == pytest.approx(1.25)
    assert g.t_min("wait") == pytest.approx(0.5 + 1.0)
    assert g.t_max("wait") == pytest.approx(2.0 + 0.5 + 0.5 + 1.0)
    assert g.t_min("a") == pytest.approx(1.5 + 1.5)
    assert g.pauses == {"wait"} and g.fillers == {"okay"}
    assert g.kind("okay") == "filler"


def test_the_pause_rule_makes_the_speech_end_at_the_target() -> None:
    g = small()
    # at a = 1 from the end of 'a' with t_x = 3.0 s left: the pause fills what 'b' leaves
    target = 3.0
    length = g.pause_length("wait", target)
    # planned with the pause at 1.25 s, 1.75 s are left: the rule says "Okay." (mid 2 s) and
    # then 'b', 2 s in all, so the pause lasts 1 s
    assert length == pytest.approx(target - 2.0)
    assert g.eta("a", 1.5, 1.5 + target) == pytest.approx(1.5 + target)
    # beyond the bounds it clips
    assert g.pause_length("wait", 0.0) == 0.5
    assert g.pause_length("wait", 100.0) == 2.0
    with pytest.raises(PhraseGraphError, match="'a' is not a pause"):
        g.pause_length("a", 1.0)


# ---------------------------------------------------------------- YAML validation
GOOD = """
start: a
pause: 0.5
phrases:
  a: {text: "Go.", next: [wait]}
  wait: {pause: [0.5, 2], next: [okay, b]}
  okay: {filler: true, text: "Okay.", next: [b]}
  b: {text: "Done.", next: []}
"""


def test_a_graph_file_with_pauses_and_fillers_loads(tmp_path: Path, clips: ClipLibrary) -> None:
    g = PhraseGraph.load(write(tmp_path, GOOD), clips)
    assert g.pauses == {"wait"} and g.fillers == {"okay"}
    assert g.phrases["wait"].bounds == (0.5, 2.0)


BAD = {
    "reversed pause bounds": (
        GOOD.replace("[0.5, 2]", "[2, 0.5]"),
        "pause 'wait': pause bounds are reversed: min 2 > max 0.5",
    ),
    "negative pause bound": (
        GOOD.replace("[0.5, 2]", "[-1, 2]"),
        "pause 'wait': pause bounds must not be negative",
    ),
    "pause bounds not a pair": (GOOD.replace("[0.5, 2]", "1.5"), "'pause' must be \\[min, max\\]"),
    "pause too long": (GOOD.replace("[0.5, 2]", "[1, 30]"), "pause max must be at most 10"),
    "filler without audio": (
        GOOD.replace(
            'okay: {filler: true, text: "Okay.", next: [b]}', "okay: {filler: true, next: [b]}"
        ),
        "filler 'okay': no audio: give 'text'",
    ),
    "pause with text": (
        GOOD.replace("wait: {pause: [0.5, 2],", 'wait: {pause: [0.5, 2], text: "hm",'),
        "pause 'wait': a pause is silence: it has no 'text'",
    ),
    "cycle": (
        GOOD.replace(
            'okay: {filler: true, text: "Okay.", next: [b]}',
            'okay: {filler: true, text: "Okay.", next: [a]}',
        ),
        "on a cycle",
    ),
    "unreachable vertex": (
        GOOD + '  lost: {text: "Never said.", next: [b]}\n',
        "phrase 'lost': unreachable, no speech from 'a' says it",
    ),
    "pause at the start": (
        GOOD.replace("start: a", "start: wait"),
        "pause 'wait': the speech cannot start",
    ),
    "pause at the end": (
        GOOD.replace(
            'b: {text: "Done.", next: []}',
            'b: {text: "Done.", next: [end]}\n  end: {pause: [1, 2], next: []}',
        ),
        "pause 'end': the speech cannot end with a pause",
    ),
    "pause after pause": (
        GOOD.replace(
            "wait: {pause: [0.5, 2], next: [okay, b]}",
            "wait: {pause: [0.5, 2], next: [wait2]}\n  wait2: {pause: [0, 1], next: [okay, b]}",
        ),
        "pause 'wait2': follows pause 'wait'",
    ),
    "filler not a bool": (
        GOOD.replace("filler: true", "filler: 3"),
        "'filler' must be true or false",
    ),
}


@pytest.mark.parametrize("case", sorted(BAD))
def test_bad_graphs_are_named_with_file_vertex_and_reason(
    case: str, tmp_path: Path, clips: ClipLibrary
) -> None:
    text, pattern = BAD[case]
    path = write(tmp_path, text)
    with pytest.raises(PhraseGraphError, match=pattern) as err:
        PhraseGraph.load(path, clips)
    assert str(path) in str(err.value)


def test_a_filler_longer_than_a_word_or_two_is_refused(tmp_path: Path, clips: ClipLibrary) -> None:
    long = "This filler is a whole sentence and lasts far too long to be a filler at all."
    path = write(tmp_path, GOOD.replace('text: "Okay."', f'text: "{long}"'))
    with pytest.raises(PhraseGraphError, match=r"filler 'okay': its clip lasts .* at most 1.5 s"):
        PhraseGraph.load(path, clips)


def test_phrase_objects_check_their_kind() -> None:
    with pytest.raises(PhraseGraphError, match="kind must be one of"):
        Phrase("x", "hi", None, (), "noise")
    with pytest.raises(PhraseGraphError, match="only a pause has bounds"):
        Phrase("x", "hi", None, (), "phrase", (0.0, 1.0))
    with pytest.raises(PhraseGraphError, match="a pause has no 'text'"):
        Phrase("x", "hi", None, (), "pause", (0.0, 1.0))


# ---------------------------------------------------------------- the shipped graphs
def test_the_default_graph_has_pauses_legs_and_shorter_late_wordings(
    clips: ClipLibrary,
) -> None:
    g = PhraseGraph.load(default_graph_path("default"), clips)
    study = PhraseGraph.load(default_graph_path("study"), clips)
    assert g.pauses and g.segment_names == ("out", "back", "again")
    # no filler before a leg's first words: they start as the hand enters the leg
    assert not g.fillers and len(g.repeats) == 3  # a line that may repeat in every leg
    assert default_graph_path("lc") == default_graph_path("default")
    # the study's graph has no late wording shorter than "I want you to retract your arm"
    assert g.speech_range()[0] < study.t_min(study.start) - 2.0
    cov = coverage(g)
    assert cov.covers(8.0, 16.0), cov.natural
    assert not coverage(study).covers(8.0, 16.0)  # the study's graph starts at 10.4 s


def test_the_study_graph_ships_byte_for_byte(clips: ClipLibrary) -> None:
    import hashlib

    digest = hashlib.sha256(default_graph_path("study").read_bytes()).hexdigest()
    # the study's LC graph as it shipped before pauses existed (models record this digest)
    assert digest == "9b3a80bd0c34bd5b2648c856c930d74589ca8287f7cb914063ae222278fd6927"
    assert not PhraseGraph.load(default_graph_path("study"), clips).pauses


def test_every_path_of_the_default_graph_alternates_speech_and_silence(clips: ClipLibrary) -> None:
    g = PhraseGraph.load(default_graph_path("default"), clips)
    # every path starts and ends with words and never has two silences in a row but for the
    # waits the graph adds (a gate before a leg's words, the wait before the last phrase): no
    # pause starts, ends or follows another (checked on the edges: the paths number in the
    # millions)
    assert g.start not in g.pauses
    waits = {u for u in g.opened if g.is_gate(u) or u.endswith("#wait")}
    for u in g.phrases:
        assert not (u in g.pauses and g.is_terminal(u))
        assert not (u in g.pauses and any(v in g.pauses - waits for v in g.children(u)))
    assert g.count_paths() > 100_000 and np.isfinite(g.t_max(g.start))
