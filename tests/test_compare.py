"""``langctrl compare``: a tiny end-to-end run, and bad arguments that must write nothing."""

from __future__ import annotations

import csv
import subprocess
import sys
from pathlib import Path

import pytest

from eval.compare import policy_names
from langctrl.jobs.compare import main

ROOT = Path(__file__).resolve().parents[1]
SESSIONS = ROOT.parent / "shared" / "sessions"


def test_smoke_run_writes_every_output(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "cmp"
    args = ["--policies", "ac,lc", "--users", "synthetic:1", "--seed", "3", "--out", str(out)]
    rc = main([*args, "--workers", "1", "--decision-hz", "50"])
    assert rc == 0
    said = capsys.readouterr().out  # the verdict, plain (not a terminal)
    assert "median |AM| (s)" in said and "\x1b[" not in said
    assert "LC's |AM| <= 1 s in every session" in said and "n/a" in said  # no LC-noAP here
    assert str(out / "summary.md") in said and said.rstrip().splitlines()[-1].startswith("wrote")
    rows = list(csv.DictReader((out / "sessions.csv").open()))
    assert [r["policy"] for r in rows] == ["ac", "lc"]
    for col in ("am", "abs_am", "em_mean_abs", "a_mean", "a_dev", "p_mean", "coop_mean"):
        assert col in rows[0]
    for col in ("a_within_0_1", "pause_share", "filler_share"):  # shares of the speech time
        assert 0.0 <= float(rows[1][col]) <= 1.0
    assert "pauses %" in said and "fillers %" in said and "|a-1|<=0.1 %" in said
    assert float(rows[0]["a_dev"]) == pytest.approx(0.0)  # AC never changes its pace
    assert (out / "summary.md").read_text().startswith("# ")
    assert (out / "summary.png").stat().st_size > 10_000
    for pol in ("ac", "lc"):
        assert (out / "sessions" / f"{pol}_s3.png").stat().st_size > 10_000
        assert (out / "sessions" / f"{pol}_s3.wav").stat().st_size > 10_000
    assert (out / "config.json").is_file()
    assert not list(tmp_path.glob(".cmp.tmp-*"))


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--policies", "ac,telepathy"], "telepathy"),
        (["--policies", "ppo:/no/such/model.zip"], "model.zip"),
        (["--decision-hz", "7"], "decision-hz"),
        (["--users", "synthetic:zero"], "synthetic:N"),
        (["--users", "synthetic:²"], "synthetic:N"),
        (["--users", "synthetic:10000000000"], "at most 10000"),
        (["--policies", "ppo:"], "ppo:PATH needs the path"),
    ],
)
def test_bad_arguments_exit_nonzero_and_write_nothing(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], args: list[str], message: str
) -> None:
    out = tmp_path / "out"
    assert _status([*args, "--out", str(out)]) == 2  # --users: the parser's own check, exit 2
    assert message in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == []


def _status(argv: list[str]) -> int:
    """``langctrl compare``'s exit status: main's, or the parser's (a usage error exits)."""
    try:
        return main(argv)
    except SystemExit as exc:
        return int(exc.code or 0)


def test_bad_phrase_graph_and_bad_session(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    graph = tmp_path / "loop.yaml"
    graph.write_text("start: a\nphrases:\n  a:\n    text: hi\n    next: [a]\n")
    out = tmp_path / "out"
    assert main(["--phrase-graph", str(graph), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "loop.yaml" in err and "'a'" in err
    sessions = tmp_path / "sessions"
    sessions.mkdir()
    (sessions / "u1.csv").write_text("t,speed\n0,1\n")
    assert main(["--sessions", str(sessions), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "u1.csv" in err and "cooperation" in err
    assert not out.exists()


def test_cli_entry_point_help() -> None:
    res = subprocess.run(
        [sys.executable, "-m", "langctrl", "compare", "--help"],
        capture_output=True,
        text=True,
        check=False,
    )
    assert res.returncode == 0 and "--policies" in res.stdout


@pytest.mark.skipif(not SESSIONS.is_dir(), reason="recorded sessions not available")
def test_replay_sessions_one_episode_per_csv(tmp_path: Path) -> None:
    out = tmp_path / "replay"
    args = ["--policies", "lc", "--sessions", str(SESSIONS), "--pattern", "u2_lc.csv"]
    rc = main([*args, "--out", str(out), "--workers", "1", "--no-audio", "--no-figures"])
    assert rc == 0
    rows = list(csv.DictReader((out / "sessions.csv").open()))
    assert [(r["policy"], r["user"]) for r in rows] == [("lc", "u2_lc")]


def test_lc_speaks_the_default_graph_unless_told_the_study_s(tmp_path: Path) -> None:
    from eval.episode import EpisodeLog

    graphs = {}
    for name, extra in (("default", []), ("study", ["--graph", "study"])):
        out = tmp_path / name
        args = ["--policies", "lc", "--users", "synthetic:1", "--seed", "4", "--out", str(out)]
        rc = main([*args, *extra, "--workers", "1", "--no-audio", "--no-figures"])
        assert rc == 0
        log = EpisodeLog.load_npz(out / "sessions" / "lc_s4.npz")
        graphs[name] = (log.phrase_graph, {u.phrase for u in log.utterances})
        rows = list(csv.DictReader((out / "sessions.csv").open()))
        assert float(rows[0]["pause_share"]) > 0.0
    assert graphs["default"][0] == "default" and graphs["study"][0] == "study"
    assert "intro" in graphs["study"][1] and "intro" not in graphs["default"][1]
    assert any(u.startswith("pause_") for u in graphs["default"][1])


def test_policy_names_are_distinct_for_several_learned_models() -> None:
    assert policy_names(["lc", "ppo:models/a.zip"]) == {"lc": "lc", "ppo:models/a.zip": "ppo"}
    names = policy_names(["lc", "ppo:runs/x/m.zip", "ppo:runs/y/m.zip", "ppo:runs/z/k"])
    assert names == {
        "lc": "lc",
        "ppo:runs/x/m.zip": "ppo-m",
        "ppo:runs/y/m.zip": "ppo-m-2",
        "ppo:runs/z/k": "ppo-k",
    }


def test_video_flag_writes_a_video_per_episode_with_the_wav_as_sound(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """--video hands each episode's log and its WAV's audio to eval.video (encoding is tested
    in test_video.py; here a stand-in records the calls, so the test stays fast)."""
    import numpy as np
    import soundfile as sf

    import eval.video

    calls: list[tuple[object, Path, np.ndarray, int]] = []

    def fake_write_video(log: object, out: Path, audio: np.ndarray, sr: int) -> Path:
        calls.append((log, Path(out), np.asarray(audio), sr))
        Path(out).write_bytes(b"mp4")
        return Path(out)

    monkeypatch.setattr(eval.video, "write_video", fake_write_video)
    out = tmp_path / "cmp"
    args = ["--policies", "lc", "--users", "synthetic:1", "--seed", "3", "--out", str(out)]
    assert main([*args, "--workers", "1", "--decision-hz", "50", "--video", "--no-figures"]) == 0
    assert len(calls) == 1
    log, path, audio, sr = calls[0]
    assert path.name == "lc_s3.mp4" and (out / "sessions" / "lc_s3.mp4").is_file()
    assert getattr(log, "has_scene", False)
    wav, wav_sr = sf.read(out / "sessions" / "lc_s3.wav", dtype="float32")
    assert sr == wav_sr and audio.shape == wav.shape
    assert np.abs(audio - wav).max() < 1e-4  # the WAV is the same audio, as 16-bit PCM


def test_existing_out_is_refused_and_its_files_kept(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The issue's repro: langctrl compare --out DIR on a directory with a user's file in it."""
    out = tmp_path / "v"
    out.mkdir()
    (out / "a.txt").write_text("keep")
    args = ["--policies", "ac", "--users", "synthetic:1", "--out", str(out), "--workers", "1"]
    fast = ["--no-audio", "--no-figures", "--decision-hz", "50"]
    assert main([*args, *fast]) == 2
    err = capsys.readouterr().err
    assert "not empty" in err and "--overwrite" in err
    assert sorted(p.name for p in out.iterdir()) == ["a.txt"]
    # --overwrite writes the outputs beside it and leaves it alone; again, it replaces them
    assert main([*args, *fast, "--overwrite"]) == 0
    assert (out / "a.txt").read_text() == "keep"
    first = (out / "sessions.csv").read_text()
    assert main([*args, *fast, "--overwrite", "--seed", "1"]) == 0
    assert (out / "a.txt").read_text() == "keep"
    assert (out / "sessions.csv").read_text() != first
    assert sorted(p.name for p in (out / "sessions").iterdir()) == ["ac_s1.npz"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["v"]  # no temporary left
    rows = list(csv.DictReader((out / "sessions.csv").open()))
    assert rows[0]["protective_stop"] == "0.0" and rows[0]["stop_limit"] == ""
    assert "Protective stops" in (out / "summary.md").read_text()


def test_negative_seed_is_a_usage_error(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as info:
        main(["--seed", "-5", "--out", str(tmp_path / "out")])
    assert info.value.code == 2
    assert "argument --seed: must be >= 0, got -5" in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == []


def test_out_under_a_file_is_named(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    blocker = tmp_path / "file"
    blocker.write_text("x")
    assert main(["--out", str(blocker / "out")]) == 2
    assert "is a file, not a directory" in capsys.readouterr().err
    assert main(["--out", str(blocker)]) == 2
    assert "not a directory" in capsys.readouterr().err
    assert blocker.read_text() == "x"


@pytest.mark.skipif(sys.platform != "linux", reason="uses /sys, read-only even for root")
def test_unwritable_out_is_named(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["--users", "synthetic:1", "--out", "/sys/langctrl-test/out"]) == 2
    assert "cannot write there" in capsys.readouterr().err


def test_parallel_jobs_run_longest_first_and_return_rows_in_job_order(tmp_path: Path) -> None:
    from eval.compare import Job, decision_rate, run_jobs

    def job(policy: str, user: int, hz: int | None) -> Job:
        return Job(policy, f"s{user}", user, None, str(tmp_path), False, False, hz)

    jobs = [job("ac", 0, None), job("ac", 1, None), job("lc", 0, 50), job("lc", 1, 50)]
    assert [decision_rate(j) for j in jobs] == [25, 25, 50, 50]
    serial = run_jobs(jobs, 1)
    parallel = run_jobs(jobs, 2)
    order = [(r["policy"], r["user"]) for r in parallel]
    assert order == [("ac", "s0"), ("ac", "s1"), ("lc", "s0"), ("lc", "s1")]
    # the same rows; NaN (AC's one wording has no legs) compared as NaN, not as an object
    assert [list(r) for r in parallel] == [list(r) for r in serial]
    for a, b in zip(parallel, serial, strict=True):
        same = {k: a[k] == b[k] or (a[k] != a[k] and b[k] != b[k]) for k in a}
        assert all(same.values()), [k for k, ok in same.items() if not ok]


def test_a_failing_parallel_episode_raises_its_error(tmp_path: Path) -> None:
    from eval.compare import Job, run_jobs

    missing = str(tmp_path / "no_such_session.csv")
    jobs = [Job("ac", f"s{k}", k, None, str(tmp_path), False, False, None) for k in range(3)]
    jobs.insert(1, Job("lc", "ghost", 9, missing, str(tmp_path), False, False, 50))
    with pytest.raises(Exception, match="no_such_session"):
        run_jobs(jobs, 2)


def test_the_progress_bar_says_which_exercise_and_policies_it_runs(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A job of several runs (langctrl exercises: one per exercise) shows which one each bar is."""
    args = ["--policies", "ac", "--users", "synthetic:1", "--exercise", "hand_to_mouth"]
    assert main([*args, "--no-audio", "--no-figures", "--out", str(tmp_path / "o")]) == 0
    assert "hand_to_mouth: ac episodes" in capsys.readouterr().err
