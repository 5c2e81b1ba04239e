"""Smoke run of ``langctrl voice-figure`` on one LC session."""

from __future__ import annotations

from pathlib import Path

import pytest

from langctrl.jobs.compare import main as compare
from langctrl.jobs.voice_figure import main


def test_the_voice_figure_of_an_lc_session(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    run = tmp_path / "run"
    args = ["--policies", "lc", "--users", "synthetic:1", "--no-audio", "--no-figures"]
    assert compare([*args, "--workers", "1", "--out", str(run)]) == 0
    out = tmp_path / "voice.png"
    assert main([str(run / "sessions" / "lc_s0.npz"), "--out", str(out)]) == 0
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and out.stat().st_size > 20_000
    assert f"wrote {out}" in capsys.readouterr().out
    with pytest.raises(SystemExit):
        main([str(run / "sessions" / "lc_s0.npz"), "--out", str(tmp_path / "no" / "x.png")])
    assert "does not exist" in capsys.readouterr().err
