"""A script checked against its exercise: motion times (cached), warnings, the two CLIs."""

from __future__ import annotations

from pathlib import Path

import pytest

from langctrl.jobs.exercise import main as exercise_main
from langctrl.jobs.speech import main as speech_main
from langenv.exercise import resolve_exercise
from langenv.script_fit import MotionTimes, fit_warnings, motion_times
from langenv.speech.audio import ClipLibrary
from langenv.speech.author import author
from langenv.speech.graph import PhraseGraph

SHORT = "Reach forward.\nAnd bring it back.\nAnd you're done.\n"
LONG = (
    "@pause 0.3\nI want you to reach forward and up, nice and slowly.\n"
    "[We are reaching up together.] | [Up, up, up.]\n"
    "And now bring your hand back towards your body. | Bring it back.\n"
    "[Keep going.] | [Nice and slow.] | [Almost there.] (repeat 12, gap 0.5-2)\n"
    "And you're done.\n"
)


@pytest.fixture(scope="module")
def flexion_times() -> MotionTimes:
    return motion_times(resolve_exercise("shoulder_flexion"))


def graph_of(tmp_path: Path, text: str, clips: ClipLibrary) -> PhraseGraph:
    script = tmp_path / "s.txt"
    script.write_text(text)
    return author(script, tmp_path / "s.yaml", clips)


def test_motion_times_are_the_population_s_and_cached(
    flexion_times: MotionTimes, monkeypatch: pytest.MonkeyPatch
) -> None:
    pop = flexion_times.population
    assert len(pop) == 48 and list(pop) == sorted(pop)
    assert 9.0 < flexion_times.nominal < pop[0] + 1.0  # resisting people are slower
    assert flexion_times.q05 <= flexion_times.q95 <= pop[-1]
    legs = flexion_times.legs  # each leg's times: the motion's, cut where the guide switches
    assert len(legs) == 3 and all(len(leg.population) == 48 for leg in legs)
    assert sum(leg.nominal for leg in legs) == pytest.approx(flexion_times.nominal, abs=1e-9)
    assert sum(leg.population[-1] for leg in legs) >= pop[-1] - 1e-9  # slowest of each leg
    assert sum(leg.population[0] for leg in legs) <= pop[0] + 1e-9
    import langenv.script_fit as fit

    monkeypatch.setattr(fit, "_population", lambda *a: pytest.fail("simulated again"))
    assert motion_times(resolve_exercise("shoulder_flexion")) == flexion_times


def test_a_short_script_is_warned_about_with_what_would_close_the_gap(
    tmp_path: Path, clips: ClipLibrary, flexion_times: MotionTimes
) -> None:
    warnings = fit_warnings(graph_of(tmp_path, SHORT, clips), flexion_times)
    assert len(warnings) == 2 and all(w.startswith("warning: s.yaml: ") for w in warnings)
    assert "even when nobody resists" in warnings[0]
    assert "slowest 5 % of 48 synthetic people" in warnings[1]
    assert "(repeat " in warnings[1] and "silence" in warnings[1]


def test_a_script_with_a_repeat_covers_the_population(
    tmp_path: Path, clips: ClipLibrary, flexion_times: MotionTimes
) -> None:
    assert fit_warnings(graph_of(tmp_path, LONG, clips), flexion_times) == []


def test_without_the_final_wait_the_warning_says_the_speech_runs_out(
    tmp_path: Path, clips: ClipLibrary, flexion_times: MotionTimes
) -> None:
    graph = graph_of(tmp_path, "@final-wait off\n" + SHORT, clips)
    assert any("would run out" in w for w in fit_warnings(graph, flexion_times))


def test_speech_author_with_an_exercise_prints_the_warnings(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], flexion_times: MotionTimes
) -> None:
    script = tmp_path / "s.txt"
    script.write_text(SHORT)
    args = ["author", str(script), "--out", str(tmp_path / "g.yaml"), "--exercise"]
    assert speech_main([*args, "shoulder_flexion", "--cache-dir", str(tmp_path / "c")]) == 0
    out = capsys.readouterr().out
    assert "against exercise shoulder_flexion:" in out
    warnings = [line for line in out.splitlines() if line.startswith("warning: g.yaml")]
    assert len(warnings) == 3 and "no @leg marks" in warnings[2]  # an unmarked script
    # an unknown exercise is refused before anything is written
    assert speech_main([*args[:-1], "--overwrite", "--exercise", "nowhere"]) == 1
    assert "nowhere" in capsys.readouterr().err


def _new_exercise(tmp_path: Path) -> Path:
    """Shoulder flexion as a new exercise whose script files are not written yet."""
    from langenv.exercise import SHIPPED_EXERCISES

    text = SHIPPED_EXERCISES["shoulder_flexion"].read_text(encoding="utf-8")
    old = (
        "script: {graph: scripts/shoulder_flexion_lc.yaml, "
        "single: scripts/shoulder_flexion_single.yaml}"
    )
    assert old in text
    mine = tmp_path / "my.yaml"
    mine.write_text(
        text.replace(old, "script: {graph: scripts/my.yaml, single: scripts/my_single.yaml}")
    )
    (tmp_path / "scripts").mkdir()
    return mine


def test_the_first_script_of_a_new_exercise_is_authored_against_it(
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    flexion_times: MotionTimes,
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """The exercise names the scripts about to be written: authoring them against it works (its
    own script entries are what is being made), and then the exercise loads."""
    import langenv.script_fit as fit

    mine = _new_exercise(tmp_path)
    monkeypatch.setattr(fit, "motion_times", lambda *a, **k: flexion_times)
    script = tmp_path / "my.txt"
    script.write_text(SHORT)
    for out in ("my.yaml", "my_single.yaml"):
        args = ["author", str(script), "--out", str(tmp_path / "scripts" / out)]
        assert speech_main([*args, "--exercise", str(mine), "--cache-dir", str(tmp_path)]) == 0
        assert "against exercise shoulder_flexion:" in capsys.readouterr().out
    assert resolve_exercise(mine).graph == str(tmp_path / "scripts" / "my.yaml")


def test_a_missing_script_is_still_refused_outside_authoring(tmp_path: Path) -> None:
    from langenv.errors import ExerciseError

    with pytest.raises(ExerciseError, match=r"script.graph: 'scripts/my.yaml'"):
        resolve_exercise(_new_exercise(tmp_path))


def test_motion_times_of_an_exercise_whose_words_are_not_written(tmp_path: Path) -> None:
    """The words do not move the arm at pace 1: the population is timed without them."""
    import langenv.script_fit as fit

    ex = resolve_exercise(_new_exercise(tmp_path), unwritten_scripts=True)
    shipped = resolve_exercise("shoulder_flexion")
    assert fit._population(ex, 2) == fit._population(shipped, 2)


def test_exercise_check_reports_the_script_against_the_people(
    capsys: pytest.CaptureFixture[str], flexion_times: MotionTimes
) -> None:
    assert exercise_main(["check", "shoulder_flexion"]) == 0
    out = capsys.readouterr().out
    assert "48 synthetic people at pace 1" in out and "words of shoulder_flexion_lc.yaml" in out
    assert "  leg reach: " in out and "  leg again: " in out  # each leg's times and words
    warnings = [line for line in out.splitlines() if line.startswith("warning:")]
    assert all(" leg '" in w for w in warnings)  # the whole motion is covered; legs may not be


def test_the_cache_key_follows_the_robot_model(monkeypatch: pytest.MonkeyPatch) -> None:
    """The population's motion times are simulated on the MuJoCo model (langenv/robot/ur5.xml):
    an edit of it must not be answered from the cache with the times of the old model."""
    import langenv.script_fit as fit
    from langenv.robot.arm import UR5_XML

    exercise = resolve_exercise("shoulder_flexion")
    before = fit._key(exercise, 48)
    real = Path.read_bytes

    def edited(self: Path) -> bytes:
        data = real(self)
        return data + b"<!-- damping changed -->" if self.resolve() == UR5_XML.resolve() else data

    monkeypatch.setattr(Path, "read_bytes", edited)
    assert fit._key(exercise, 48) != before
