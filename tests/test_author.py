"""Phrase graphs written from plain-text scripts: parsing, named errors, the shipped round trip."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from langctrl.jobs.speech import main
from langenv.errors import ScriptError
from langenv.speech.audio import ClipLibrary
from langenv.speech.author import author, graph_yaml, parse_script
from langenv.speech.coverage import coverage
from langenv.speech.graph import GRAPHS_DIR, PhraseGraph, default_graph_path


@pytest.fixture(autouse=True)
def tts_cache(tmp_path_factory: pytest.TempPathFactory, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("LANGCTRL_CACHE", str(tmp_path_factory.getbasetemp() / "tts-cache"))


SCRIPT = """\
# a comment
@pause 0.5
Move your hand away from your body.
(pause 0.5-2)
[Glide really smoothly.] | Slide, slide.
{okay|so} [Good,] and back to the middle.
And you're done.
"""


def test_a_script_becomes_the_graph_it_describes() -> None:
    s = parse_script(SCRIPT, "s.txt")
    v = s.vertices
    assert s.pause == 0.5 and s.start == "move_hand_away"
    assert [x.kind for x in v.values()].count("pause") == 1
    pause = v["pause_4"]
    assert pause.bounds == (0.5, 2.0)
    # line 5 may be skipped ("[Glide really smoothly.]" is all optional): the pause may go
    # straight on to line 6's fillers and wordings
    assert pause.next == ["glide_really_smoothly", "slide_slide", *v["slide_slide"].next]
    assert v["slide_slide"].next == v["glide_really_smoothly"].next
    assert v["glide_really_smoothly"].next == ["okay", "so", "good_back_middle", "back_middle"]
    assert v["okay"].kind == "filler" and v["okay"].text == "Okay"
    assert v["okay"].next == ["good_back_middle", "back_middle"]
    assert v["back_middle"].text == "And back to the middle."
    assert v["good_back_middle"].text == "Good, and back to the middle."
    assert v["done"].next == [] and (v["done"].line, v["done"].column) == (7, 1)
    text = graph_yaml(s, "s.txt")
    assert text == graph_yaml(parse_script(SCRIPT, "s.txt"), "s.txt")  # deterministic
    assert "filler: true" in text and "pause: [0.5, 2]" in text


BAD_SCRIPTS = {
    "unclosed bracket": ("Go.\n[Glide really\n", "s.txt:2:1: '[' is not closed"),
    "bracket closing nothing": ("Go.\nGlide] here.\n", "s.txt:2:6: ']' closes nothing"),
    "nested brackets": ("Go.\n[Glide [really]]\n", "s.txt:2:8: '[' inside '['"),
    "empty alternative": ("Go.\nSlide. |  | Glide.\n", "s.txt:2:9: empty alternative"),
    "empty optional": ("Go.\nSlide [] now.\n", "s.txt:2:7: empty '[]'"),
    "pause without bounds": ("Go.\n(pause)\nDone.\n", "s.txt:2:1: '(pause)' is not a pause"),
    "reversed pause": ("Go.\n(pause 3-1)\nDone.\n", "s.txt:2:1: pause bounds are reversed"),
    "pause too long": ("Go.\n(pause 1-30)\nDone.\n", "s.txt:2:1: a pause lasts at most 10 s"),
    "not a pause": ("Go.\n(slowly)\nDone.\n", "s.txt:2:1: '(slowly)' is not a pause"),
    "empty filler": ("Go.\n{okay|} Done.\n", "s.txt:2:1: '{okay|}': fillers are words"),
    "first line with alternatives": ("Go. | Move.\nDone.\n", "s.txt:1:7: the speech starts"),
    "script starting with a pause": ("(pause 1-2)\nDone.\n", "s.txt:1:1: the speech starts"),
    "two pauses in a row": (
        "Go.\n(pause 1-2)\n[Slide.]\n(pause 0.5-1)\nDone.\n",
        "s.txt:4:1: this pause can follow the pause of line 2",
    ),
    "ends with a pause": ("Go.\nDone.\n(pause 1-2)\n", "s.txt:3:1: the speech can end with"),
    "no steps": ("# nothing\n\n", "s.txt: the script has no steps"),
    "unknown directive": ("@gap 1\nGo.\n", "s.txt:1:1: unknown directive '@gap'"),
    "late directive": ("Go.\n@pause 1\n", "s.txt:2:1: @pause must come before"),
    "bad directive value": ("@pause fast\nGo.\n", "s.txt:1:1: @pause takes seconds"),
    "no words": ("Go.\n... | Slide.\n", "s.txt:2:1: '...' has no words to say"),
}


@pytest.mark.parametrize("case", sorted(BAD_SCRIPTS))
def test_bad_scripts_are_named_errors_with_line_and_column(case: str) -> None:
    source, message = BAD_SCRIPTS[case]
    with pytest.raises(ScriptError) as err:
        parse_script(source, "s.txt")
    assert message in str(err.value)


@pytest.mark.parametrize("case", ["unclosed bracket", "reversed pause", "ends with a pause"])
def test_the_command_line_reports_a_bad_script_and_writes_nothing(
    case: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    script = tmp_path / "s.txt"
    script.write_text(BAD_SCRIPTS[case][0])
    out = tmp_path / "g.yaml"
    assert main(["author", str(script), "--out", str(out)]) == 1
    err = capsys.readouterr().err
    assert err.startswith("error: ") and "Traceback" not in err
    assert f"{script}:" in err and BAD_SCRIPTS[case][1].split(": ", 1)[1] in err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["s.txt"]  # no file, no temporary


def test_every_error_of_a_script_is_shown_at_once(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A script with three errors on three lines: all three, in order, each with its line and
    column; the lines between them read as they are."""
    script = tmp_path / "s.txt"
    script.write_text(
        "Reach forward.\n[Keep going. | Nice and slow.\nAnd back. (pause 3-1)\n"
        "@voice robot\nAnd you're done.\n"
    )
    assert main(["author", str(script), "--out", str(tmp_path / "g.yaml")]) == 1
    err = capsys.readouterr().err.splitlines()
    assert [line.split(": ")[1].rsplit(":", 2)[1:] for line in err] == [
        ["2", "1"],
        ["3", "11"],
        ["4", "1"],
    ]
    assert "is not closed" in err[0] and "reversed" in err[1] and "@voice" in err[2]
    assert not (tmp_path / "g.yaml").exists()


def test_a_graph_error_the_script_makes_names_its_line(tmp_path: Path) -> None:
    script = tmp_path / "s.txt"
    long = "this is far too long to be a filler word"
    script.write_text(f"Go.\n{{{long}}} Done.\n")
    with pytest.raises(ScriptError, match=r"s.txt:2:1: filler '\w+': its clip lasts"):
        author(script, tmp_path / "g.yaml", ClipLibrary(cache_dir=tmp_path / "tts"))
    assert not (tmp_path / "g.yaml").exists()


def test_ids_that_yaml_reads_as_other_things_are_written_quoted(tmp_path: Path) -> None:
    """The line "Yes." makes the id ``yes``, which YAML reads as true (and ``no``, ``on``, ``off``,
    ``null`` as other things than strings): the graph the script made failed to load with
    "'next' must be a list of phrase ids, got [True, False]"."""
    script = tmp_path / "s.txt"
    script.write_text("Go now.\n{yes|okay} Keep going. | No. | Null. (repeat 3)\nOn.\n")
    g = author(script, tmp_path / "g.yaml", ClipLibrary(cache_dir=tmp_path / "tts"))
    assert {"yes", "no", "null", "on"} <= set(g.source_phrases)
    assert set(g.repeats["again_2"].phrases) == {"keep_going", "no", "null"}
    assert g.children("yes") == ("keep_going",)


def test_author_writes_a_valid_graph_and_prints_its_coverage(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    script = tmp_path / "s.txt"
    script.write_text(SCRIPT)
    out = tmp_path / "g.yaml"
    assert main(["author", str(script), "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "3 fillers" not in printed and "2 fillers" in printed and "1 pause" in printed
    assert "at |a - 1| <= 0.1:" in printed and "at a in [0.6, 1.4]:" in printed
    g = PhraseGraph.load(out)
    assert {u for u, ph in g.source_phrases.items() if ph.is_pause} == {"pause_4"}
    assert g.fillers == {"okay", "so"} and g.final_wait and g.opened  # the last phrase waits
    assert main(["author", str(script), "--out", str(out)]) == 1  # no silent overwrite
    assert "--overwrite" in capsys.readouterr().err
    assert main(["check", str(out), "--coverage"]) == 0
    assert "coverage:" in capsys.readouterr().out


SHIPPED_SCRIPTS = sorted(
    [*GRAPHS_DIR.glob("*.txt"), *(GRAPHS_DIR.parent / "exercises" / "scripts").glob("*.txt")]
)


def test_the_shipped_default_graph_is_what_author_makes_of_its_script() -> None:
    script = GRAPHS_DIR / "default.txt"
    made = graph_yaml(parse_script(script.read_text(encoding="utf-8"), script), script.name)
    assert made == default_graph_path("default").read_text(encoding="utf-8")


@pytest.mark.parametrize("script", SHIPPED_SCRIPTS, ids=lambda p: p.name)
def test_every_shipped_script_sits_beside_the_graph_author_makes_of_it(script: Path) -> None:
    made = graph_yaml(parse_script(script.read_text(encoding="utf-8"), script), script.name)
    assert made == script.with_suffix(".yaml").read_text(encoding="utf-8")


def test_the_default_graph_covers_8_to_16_s_of_motion_at_a_natural_pace() -> None:
    cov = coverage(PhraseGraph.load(default_graph_path("default")))
    lo, hi = cov.natural_range
    assert lo <= 8.0 and hi >= 16.0, cov
    assert cov.covers(8.0, 16.0)
    assert cov.full_range[0] < lo and cov.full_range[1] > hi


def test_author_runs_as_a_module(tmp_path: Path) -> None:
    script = tmp_path / "s.txt"
    script.write_text("Go.\n(pause 0.5-1)\nDone.\n")
    res = subprocess.run(
        [
            sys.executable,
            "-m",
            "langctrl.jobs.speech",
            "author",
            str(script),
            "--out",
            str(tmp_path / "g.yaml"),
        ],
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )
    assert res.returncode == 0, res.stderr
    assert "wrote" in res.stdout and "coverage:" in res.stdout
