"""`langctrl speech check|render`, and the renderers behind it."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import soundfile as sf

from langctrl.jobs.speech import main
from langenv.errors import ConfigError
from langenv.speech.audio import ClipLibrary
from langenv.speech.graph import PhraseGraph, default_graph_path
from langenv.speech.render import plan_speech, render_history, render_speech

REPO = Path(__file__).resolve().parents[1]
SESSIONS = Path(__file__).resolve().parents[2] / "shared" / "sessions"

BAD = {
    "cyclic": (
        "start: a\nphrases:\n  a: {text: Hello there., next: [b]}\n"
        "  b: {text: Slide., next: [a, end]}\n  end: {text: Done., next: []}\n",
        ["'a'", "'b'", "cycle"],
    ),
    "unknown_next": (
        "start: a\nphrases:\n  a: {text: Hello there., next: [nowhere]}\n",
        ["'a'", "'nowhere'"],
    ),
    "dead_end": (
        "start: a\nphrases:\n  a: {text: Hello., next: [b, end]}\n  b: {text: Slide., next: [c]}\n"
        "  c: {text: Glide., next: [b]}\n  end: {text: Done., next: []}\n",
        ["'b'", "'c'", "dead end"],
    ),
    "missing_audio": (
        "start: a\nphrases:\n  a: {audio: clips/nope.wav, next: []}\n",
        ["'a'", "nope.wav"],
    ),
}


@pytest.fixture(autouse=True)
def tts_cache(tmp_path_factory: pytest.TempPathFactory, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("LANGCTRL_CACHE", str(tmp_path_factory.getbasetemp() / "tts-cache"))


def write_trace(path: Path, t: np.ndarray, a: np.ndarray, t_x: np.ndarray | None = None) -> Path:
    cols = [t, a] + ([] if t_x is None else [t_x])
    header = "t,cooperation,audio_pace" + ("" if t_x is None else ",t_x")
    rows = [
        f"{r[0]:.6f},1.0," + ",".join(f"{v:.6f}" for v in r[1:]) for r in zip(*cols, strict=True)
    ]
    path.write_text(header + "\n" + "\n".join(rows) + "\n")
    return path


def test_check_prints_one_line(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["check", str(default_graph_path("study"))]) == 0
    out = capsys.readouterr().out.splitlines()
    assert len(out) == 1
    assert "16 phrases" in out[0] and "paths" in out[0] and "study.yaml" in out[0]
    assert main(["check", "default"]) == 0
    out = capsys.readouterr().out.splitlines()
    assert "legs marked" in out[0] and "pauses" in out[0] and "default.yaml" in out[0]


def test_check_accepts_shipped_names_and_lists_paths(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["check", "lc_noap", "--paths"]) == 0
    out = capsys.readouterr().out.splitlines()
    assert len(out) == 2
    assert out[0].split()[-1] == "done" and "1 path," in out[1]


def test_check_lists_the_paths_of_a_graph_with_repeats(capsys: pytest.CaptureFixture[str]) -> None:
    """The docs' ``speech check lc --paths`` on the shipped default graph: its repeat (6
    sayings of 4 wordings) makes millions of paths, so it failed with 'exceed limit=10000'. The
    paths listed say each repeat once (the plan's paths), and the line after them says so."""
    assert main(["check", "lc", "--paths"]) == 0
    out = capsys.readouterr().out.splitlines()
    graph = PhraseGraph.load(default_graph_path("default"))
    listed = [line for line in out if " > " in line]
    assert len(listed) == graph.count_paths(once=True) < graph.count_paths()
    assert not any("#gap" in line for line in listed)
    assert all(line.split()[-1] == "done" for line in listed)
    assert any("each repeat said once" in line for line in out)


@pytest.mark.parametrize("case", sorted(BAD))
def test_bad_graph_fails_naming_file_and_phrase_and_writes_nothing(
    case: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    text, fragments = BAD[case]
    graph = tmp_path / f"{case}.yaml"
    graph.write_text(text)
    assert main(["check", str(graph)]) == 1
    captured = capsys.readouterr()
    assert captured.out == ""
    for fragment in [str(graph), *fragments]:
        assert fragment in captured.err
    trace = write_trace(tmp_path / "trace.csv", np.linspace(0, 5, 6), np.ones(6))
    before = sorted(p.name for p in tmp_path.iterdir())
    out = tmp_path / "out.wav"
    assert main(["render", str(graph), str(trace), str(out)]) == 1
    err = capsys.readouterr().err
    assert str(graph) in err and fragments[0] in err
    assert not out.exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == before  # no temporary file left


@pytest.mark.parametrize(
    ("content", "fragment"),
    [
        ("t,cooperation\n0,1\n1,1\n", "missing column 'audio_pace'"),
        ("t,audio_pace\n0,1\n1,fast\n", "row 3, column 'audio_pace'"),
        ("t,audio_pace\n0,1\n0,1\n", "column 't': times must increase"),
        ("t,audio_pace\n0,1\n1,-1\n", "column 'audio_pace': must be > 0"),
        ("t,audio_pace,t_x\n0,1,nan\n1,1,3\n", "column 't_x': not finite"),
        ("t,audio_pace\n0,1\n", "at least 2 rows"),
    ],
)
def test_bad_trace_fails_naming_file_and_column(
    content: str, fragment: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    trace = tmp_path / "trace.csv"
    trace.write_text(content)
    out = tmp_path / "out.wav"
    assert main(["render", "ac", str(trace), str(out)]) == 1
    err = capsys.readouterr().err
    assert str(trace) in err and fragment in err
    assert not out.exists()


def test_render_rejects_unknown_output_type(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    trace = write_trace(tmp_path / "trace.csv", np.linspace(0, 5, 6), np.ones(6))
    assert main(["render", "ac", str(trace), str(tmp_path / "out.mp3")]) == 1
    assert "out.mp3" in capsys.readouterr().err


def test_module_entry_point_runs() -> None:
    env = dict(os.environ, PYTHONPATH=str(REPO) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    res = subprocess.run(
        [sys.executable, "-m", "langctrl.jobs.speech", "--help"],
        capture_output=True,
        text=True,
        env=env,
        cwd=REPO,
        timeout=60,
        check=False,
    )
    assert res.returncode == 0 and "check" in res.stdout and "render" in res.stdout


def test_plan_follows_rule_or_shortest_path() -> None:
    g = PhraseGraph.load(default_graph_path("study"))
    t = np.linspace(0.0, 30.0, 1501)
    plan = plan_speech(g, t, np.ones_like(t))
    assert tuple(u.phrase for u in plan) == g.shortest_path()
    assert plan[-1].t_end == pytest.approx(g.t_min(g.start), abs=1e-6)
    t_x = 18.0 - t
    plan = plan_speech(g, t, np.ones_like(t), t_x)
    assert plan[-1].t_end == pytest.approx(g.eta(g.start, g.slot(g.start), 18.0), abs=0.03)
    assert plan[0].t_start == 0.0


def test_render_history_validates_its_arguments() -> None:
    g = PhraseGraph.load(default_graph_path("study"))
    clips = ClipLibrary()
    t, a = np.array([0.0, 1.0]), np.ones(2)
    with pytest.raises(ConfigError, match=r"history\[0\]"):
        render_history(g, clips, ["done"], t, a)
    with pytest.raises(ConfigError, match=r"history\[1\]: 'side' does not follow 'intro'"):
        render_history(g, clips, ["intro", "side"], t, a)
    with pytest.raises(ConfigError, match="a must be finite and > 0"):
        render_history(g, clips, ["intro"], t, np.array([1.0, 0.0]))
    with pytest.raises(ConfigError, match="strictly increasing"):
        render_history(g, clips, ["intro"], np.array([1.0, 1.0]), a)


# ---------------------------------------------------------------- rendering (needs the vocoder)
def sound_span(y: np.ndarray, sr: int) -> tuple[float, float]:
    """First and last time (s) the signal is within 40 dB of its peak."""
    loud = np.flatnonzero(np.abs(y) > 0.01 * np.max(np.abs(y)))
    return loud[0] / sr, loud[-1] / sr


def test_render_duration_equals_the_trace(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    t = np.arange(0.0, 20.0 + 1e-9, 0.02)
    a = 1.0 + 0.3 * np.sin(2 * np.pi * t / 5.0)
    t_x = np.maximum(0.0, 14.0 - 0.9 * t)
    trace = write_trace(tmp_path / "trace.csv", t, a, t_x)
    out = tmp_path / "speech.wav"
    assert main(["render", "study", str(trace), str(out)]) == 0
    assert "wrote" in capsys.readouterr().out
    y, sr = sf.read(out)
    assert y.ndim == 1
    assert abs(y.size / sr - (t[-1] - t[0])) < 0.02
    # the speech ends where the plan (∫ a dt over clips and pauses) says it does
    plan = plan_speech(PhraseGraph.load(default_graph_path("study")), t, a, t_x)
    start, end = sound_span(y, sr)
    assert start < 0.05
    assert abs(end - plan[-1].t_end) < 0.06
    assert [p.name for p in tmp_path.iterdir() if p.name.startswith(".")] == []


def test_render_outlasting_the_trace_goes_on_at_the_last_pace() -> None:
    g = PhraseGraph.load(default_graph_path("lc_noap"))
    clips = ClipLibrary()
    t = np.array([0.0, 2.0, 4.0])
    a = np.array([1.0, 1.25, 1.25])
    y = render_speech(g, clips, t, a)
    plan = plan_speech(g, t, a)
    # ∫ a dt = path length: 2.25 s of content by t = 2, then pace 1.25
    expected = 2.0 + (g.t_min(g.start) - 2.25) / 1.25
    assert plan[-1].t_end == pytest.approx(expected, abs=0.005)
    assert abs(y.size / clips.sr - expected) < 0.02


@pytest.mark.skipif(not SESSIONS.is_dir(), reason="recorded sessions not available")
def test_render_a_recorded_session(tmp_path: Path) -> None:
    session = SESSIONS / "u1_lc.csv"
    out = tmp_path / "u1.flac"
    assert main(["render", "study", str(session), str(out)]) == 0
    y, sr = sf.read(out)
    data = np.genfromtxt(session, delimiter=",", names=True)
    plan = plan_speech(
        PhraseGraph.load(default_graph_path("study")), data["t"], data["audio_pace"], data["t_x"]
    )
    expected = max(float(data["t"][-1] - data["t"][0]), plan[-1].t_end - float(data["t"][0]))
    assert abs(y.size / sr - expected) < 0.02


@pytest.mark.parametrize(
    ("content", "fragment"),
    [
        ("t,audio_pace\n0,1\n1e7,1\n", "600 s maximum session length"),
        ("t,audio_pace\n0,1\n0.00001,1\n", "minimum spacing"),
        ("t,audio_pace\n0,1\n1,1e9\n", "column 'audio_pace': 1000000000.0 is outside"),
        ("t,audio_pace\n0,1\n1,0.001\n", "column 'audio_pace': 0.001 is outside"),
    ],
)
def test_trace_is_bounded_before_rendering(
    content: str, fragment: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A trace ending at t = 1e7 s or with an absurd pace: a named error, not 821 GiB."""
    trace = tmp_path / "trace.csv"
    trace.write_text(content)
    out = tmp_path / "out.wav"
    assert main(["render", "ac", str(trace), str(out)]) == 1
    err = capsys.readouterr().err
    assert str(trace) in err and fragment in err
    assert not out.exists()


def test_render_functions_bound_the_trace() -> None:
    g = PhraseGraph.load(default_graph_path("ac"))
    with pytest.raises(ConfigError, match="maximum session length"):
        render_history(g, ClipLibrary(), ["intro"], np.array([0.0, 1e7]), np.ones(2))
    with pytest.raises(ConfigError, match=r"a\[1\] = 1000000000.0"):
        plan_speech(g, np.array([0.0, 1.0]), np.array([1.0, 1e9]))


def test_render_never_replaces_a_file_without_overwrite(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    trace = write_trace(tmp_path / "trace.csv", np.linspace(0, 5, 6), np.ones(6))
    out = tmp_path / "out.wav"
    out.write_bytes(b"a user's recording")
    assert main(["render", "ac", str(trace), str(out)]) == 1
    assert "--overwrite" in capsys.readouterr().err
    assert out.read_bytes() == b"a user's recording"


def test_render_voices_the_pace_as_asked(tmp_path: Path) -> None:
    """--voicing overrides the graph's voice: the study's (stretched) graph voiced naturally is
    what render_history makes of it with that voice; without it, the graph's own voice."""
    from langenv.speech.audio import ClipLibrary
    from langenv.speech.render import render_history

    t = np.arange(0.0, 16.0 + 1e-9, 0.02)
    a = np.full(t.size, 0.7)
    trace = write_trace(tmp_path / "trace.csv", t, a)
    heard = {}
    for voicing in (None, "natural", "stretch"):
        out = tmp_path / f"{voicing}.wav"
        extra = [] if voicing is None else ["--voicing", voicing]
        assert main(["render", "study", str(trace), str(out), *extra]) == 0
        heard[voicing] = sf.read(out, dtype="int16")[0]
    graph = PhraseGraph.load(default_graph_path("study"))
    clips = ClipLibrary()
    plan = plan_speech(graph, t, a)
    natural = render_history(graph.with_voice("natural"), clips, plan, t, a)
    expected = np.round(np.clip(natural, -1.0, 1.0) * 32767).astype(np.int64)
    assert np.abs(heard["natural"].astype(np.int64) - expected).max() <= 4  # 16-bit PCM
    np.testing.assert_array_equal(heard[None], heard["stretch"])
    assert not np.array_equal(heard["natural"], heard["stretch"])
    with pytest.raises(SystemExit):
        main(["render", "study", str(trace), str(tmp_path / "x.wav"), "--voicing", "robotic"])
