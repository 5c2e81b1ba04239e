"""langctrl exercise list | check | render: output and exit codes 0, 1, 2."""

from __future__ import annotations

from pathlib import Path

import pytest

from langctrl.jobs.exercise import main
from langenv.exercise import SHIPPED_EXERCISES

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


def _unscripted(tmp_path: Path, script: str) -> Path:
    """Shoulder flexion, its script section replaced by ``script``."""
    text = SHIPPED_EXERCISES["shoulder_flexion"].read_text(encoding="utf-8")
    lines = [line for line in text.splitlines() if not line.startswith("script:")]
    path = tmp_path / "mine.yaml"
    path.write_text("\n".join([*lines, script]) + "\n")
    return path


@pytest.mark.parametrize(
    ("script", "warned"),
    [("script: {graph: study}", ("graph", "single")),
     ("script: {graph: scripts/shoulder_flexion_lc.yaml}", ("single",))],
)  # fmt: skip
def test_check_warns_of_the_study_s_words_naming_the_entry(
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    monkeypatch: pytest.MonkeyPatch,
    script: str,
    warned: tuple[str, ...],
) -> None:
    """A new exercise that speaks a shipped graph would say "move your hand away from your
    body" (the study's external rotation) on any path: check says so, naming the entry."""
    import langctrl.jobs.exercise as cli

    path = _unscripted(tmp_path, script)
    if "scripts/" in script:
        (tmp_path / "scripts").symlink_to(SHIPPED_EXERCISES["shoulder_flexion"].parent / "scripts")
    monkeypatch.setattr(cli, "_script_fit", lambda exercise: [])  # its own test: test_script_fit
    assert main(["check", str(path)]) == 0
    out = capsys.readouterr().out
    lines = [line for line in out.splitlines() if line.startswith("warning: mine.yaml: script.")]
    assert [line.split()[2] for line in lines] == [f"script.{r}" for r in warned]
    assert all("move your hand away from your body" in line for line in lines)


@pytest.mark.parametrize("script", ["", "script: {graph: lc}"])
def test_check_refuses_the_study_s_marked_script_naming_the_entry(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], script: str
) -> None:
    """Left out (or named), script.graph is the study's script, whose lines are marked with
    the legs of its external rotation: refused, naming the entry and what to do."""
    assert main(["check", str(_unscripted(tmp_path, script))]) == 1
    err = capsys.readouterr().err
    assert "unknown_leg: script.graph" in err and "is left out or names a shipped graph" in err
    assert "script: {graph: study}" in err


def test_the_study_s_exercise_and_the_shipped_scripts_are_not_warned_about() -> None:
    from langenv.exercise import resolve_exercise

    for name in SHIPPED_EXERCISES:
        ex = resolve_exercise(name)
        assert [ex.script_warning(r) for r in ("graph", "single")] == [None, None], name


def test_a_job_speaking_the_study_s_words_on_another_exercise_warns(tmp_path: Path) -> None:
    from langenv.exercise.script import spoken_graph

    path = _unscripted(tmp_path, "")
    with pytest.warns(UserWarning, match=r"mine.yaml: script.single is the study's 'lc-noap'"):
        assert spoken_graph("single", path).ref == "lc-noap"


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
    err = capsys.readouterr().err
    assert "unknown_key" in err and "did you mean 'line'?" in err
    assert err.rstrip().endswith("REFUSED (2 problems)")
    path.write_text(BAD + "colour: red\n")
    assert main(["check", str(path)]) == 1
    assert capsys.readouterr().err.rstrip().endswith("REFUSED (1 problem)")


def test_usage_errors_exit_2(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["check", "no_such_exercise"]) == 2
    assert "external_rotation" in capsys.readouterr().err  # the known names
    with pytest.raises(SystemExit) as info:
        main(["render", "hand_to_mouth"])  # --out missing
    assert info.value.code == 2


def test_render_draws_the_path_over_the_arm(tmp_path: Path, offscreen_gl: None) -> None:
    """Skips only without off-screen OpenGL (probed on an empty model): any failure of our
    renderer fails the test."""
    from PIL import Image

    out = tmp_path / "ex.png"
    args = ["render", "shoulder_abduction", "--out", str(out), "--width", "320", "--height", "240"]
    assert main(args) == 0
    image = Image.open(out)
    assert image.size == (320, 240)
    pixels = image.convert("RGB").getcolors(320 * 240)
    assert pixels is not None and len(pixels) > 50  # a scene, not a blank frame
