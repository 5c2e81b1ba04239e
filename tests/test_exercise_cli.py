"""python -m langenv.exercise list | check | render: output and exit codes 0, 1, 2."""

from __future__ import annotations

from pathlib import Path

import pytest

from langenv.exercise import SHIPPED_EXERCISES
from langenv.exercise.__main__ import main

BAD = """\
name: bad_one
title: Too far
start: [-0.35, -0.55, 0.06]
switch_tol: 0.035
legs:
  - name: reach
    line: {to: [-0.35, -1.2, 0.06]}
  - name: home
    line: {to: start}
"""


def test_list_shows_every_shipped_exercise(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["list"]) == 0
    lines = capsys.readouterr().out.strip().splitlines()
    assert len(lines) == len(SHIPPED_EXERCISES) >= 6
    assert any(line.startswith("external_rotation") and "study" in line for line in lines)


def test_check_passes_a_shipped_exercise(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["check", "hand_to_mouth"]) == 0
    out = capsys.readouterr().out
    assert "OK" in out and "motion at cooperation 1" in out


def test_check_refuses_an_unsafe_file_with_leg_and_reason(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = tmp_path / "bad.yaml"
    path.write_text(BAD)
    assert main(["check", str(path)]) == 1
    err = capsys.readouterr().err
    assert "bad.yaml" in err and "leg 'reach'" in err and "unreachable" in err and "REFUSED" in err


def test_check_refuses_a_malformed_file(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "bad.yaml"
    path.write_text(BAD.replace("line: {to: start}", "lines: {to: start}"))
    assert main(["check", str(path)]) == 1
    assert "unknown_key" in capsys.readouterr().err


def test_usage_errors_exit_2(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["check", "no_such_exercise"]) == 2
    assert "external_rotation" in capsys.readouterr().err  # the known names
    with pytest.raises(SystemExit) as info:
        main(["render", "hand_to_mouth"])  # --out missing
    assert info.value.code == 2


def test_render_draws_the_path_over_the_arm(tmp_path: Path) -> None:
    from PIL import Image

    out = tmp_path / "ex.png"
    try:
        code = main(
            ["render", "shoulder_abduction", "--out", str(out), "--width", "320", "--height", "240"]
        )
    except Exception as exc:  # no off-screen OpenGL on this machine
        pytest.skip(f"no off-screen rendering: {exc}")
    if code != 0:
        pytest.skip("no off-screen rendering here")
    image = Image.open(out)
    assert image.size == (320, 240)
    pixels = image.convert("RGB").getcolors(320 * 240)
    assert pixels is not None and len(pixels) > 50  # a scene, not a blank frame
