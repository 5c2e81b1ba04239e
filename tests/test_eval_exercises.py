"""Smoke run of ``langctrl exercises`` on two exercises and one user."""

from __future__ import annotations

from pathlib import Path

import pytest

from langctrl.jobs.exercises import main


@pytest.mark.slow
def test_the_exercise_table_runs_and_reads_back(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    args = ["--exercises", "external_rotation,shoulder_flexion", "--users", "synthetic:1"]
    assert main([*args, "--workers", "1", "--out", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert "| share abs(a - 1) <= 0.1 | voice natural |" in out
    medians, headline = out.split("\n\n")[:2]
    rows = [line for line in medians.splitlines() if line.startswith("| external_rotation")]
    assert [r.split(" | ")[1] for r in rows] == ["AC", "LC-noAP", "LC"]
    assert (
        len([line for line in medians.splitlines() if line.startswith("| shoulder_flexion")]) == 3
    )
    # the headline: one row per exercise, LC's one session within 1 s of its motion
    heads = [line.split(" | ") for line in headline.splitlines() if line.startswith("| ")]
    assert [h[0] for h in heads[1:]] == ["| external_rotation", "| shoulder_flexion"]
    assert all(h[1] == "1" and h[3] == "1/1" for h in heads[1:])
    # legs in step: of LC's two leg boundaries per session (the scripts mark three legs)
    assert heads[0][-1] == "legs in step |"
    assert all(h[-1].removesuffix(" |").split("/")[1] == "2" for h in heads[1:])
    # read back without running: the same table
    assert main([*args, "--out", str(tmp_path), "--table-only"]) == 0
    table = [line for line in out.splitlines() if line.startswith("|")]
    assert [line for line in capsys.readouterr().out.splitlines() if line.startswith("|")] == table


def test_unknown_exercises_are_refused_before_anything_runs(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    with pytest.raises(SystemExit):
        main(["--exercises", "cartwheel", "--out", str(tmp_path / "x")])
    assert "--exercises: unknown ['cartwheel']" in capsys.readouterr().err
    assert not (tmp_path / "x").exists()
