"""Exercise files: the format, every problem at once, the registry, the study's exercise exactly."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from langenv.control.trajectory import ArcSegment, LineSegment, default_exercise
from langenv.errors import ConfigError, ExerciseError
from langenv.exercise import (
    PROBLEM_KINDS,
    SHIPPED_EXERCISES,
    Exercise,
    Leg,
    Problem,
    exercise_path,
    load_exercise,
    resolve_exercise,
)

GOOD = """\
# A test exercise: out along x and back.
name: test_line
title: Out and back
units: {length: m, angle: deg, time: s}
start: [-0.35, -0.55, 0.06]
speed: 0.1
switch_tol: 0.035
legs:
  - name: out
    line: {to: [-0.10, -0.55, 0.06]}
  - name: back
    line: {to: start}
"""


def _write(tmp_path: Path, text: str, name: str = "ex.yaml") -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


def _kinds(tmp_path: Path, text: str) -> set[str]:
    with pytest.raises(ExerciseError) as info:
        load_exercise(_write(tmp_path, text))
    assert all(isinstance(p, Problem) for p in info.value.problems)
    return {p.kind for p in info.value.problems}


def test_the_study_exercise_is_default_exercise_exactly() -> None:
    ex = resolve_exercise("external_rotation")
    ref = default_exercise()
    assert ex.trajectory.fingerprint() == ref.fingerprint()
    assert np.array_equal(ex.trajectory.packed(), ref.packed())  # what the compiled tick reads
    assert ex.trajectory.waypoint_s.tolist() == ref.waypoint_s.tolist()
    assert ex.admittance() == type(ex.admittance())()  # the study's parameters, 10 N
    assert (ex.graph, ex.single) == ("default", "lc-noap")  # the product graph (= "lc")


def test_registry_ships_six_and_names_them() -> None:
    assert len(SHIPPED_EXERCISES) >= 6
    assert "external_rotation" in SHIPPED_EXERCISES and "hand_to_mouth" in SHIPPED_EXERCISES
    for name, path in SHIPPED_EXERCISES.items():
        ex = load_exercise(path)
        assert ex.name == name and ex.description, name  # the comment block is read
    with pytest.raises(ConfigError, match="hand_to_mouth"):
        exercise_path("no_such_exercise")


def test_a_good_file_loads_in_si_units(tmp_path: Path) -> None:
    ex = load_exercise(_write(tmp_path, GOOD))
    assert ex.leg_names == ("out", "back")
    assert ex.speed == 0.1 and ex.switch_tol == 0.035
    assert ex.admittance().propel_force == pytest.approx(8.0)
    assert ex.trajectory.length == pytest.approx(0.5)
    np.testing.assert_allclose(ex.trajectory.position(ex.trajectory.length), ex.start)
    assert ex.description.startswith("A test exercise")
    assert resolve_exercise(tmp_path / "ex.yaml").name == "test_line"


def test_arcs_turn_the_tool_and_degrees_become_radians(tmp_path: Path) -> None:
    text = GOOD.replace(
        "line: {to: [-0.10, -0.55, 0.06]}",
        "arc: {center: [-0.35, -0.25, 0.06], axis: [0, 0, 1], angle: 30}",
    )
    ex = load_exercise(_write(tmp_path, text))
    arc = ex.trajectory.segments[0]
    assert isinstance(arc, ArcSegment)
    assert arc.angle == pytest.approx(math.radians(30)) and arc.turn == pytest.approx(
        math.radians(30)
    )
    home = np.eye(3)
    rot = ex.tool_rotation(ex.leg_span(0)[1], home)
    assert rot[0, 0] == pytest.approx(math.cos(math.radians(30)))


def test_a_spline_leg_is_lines_and_arcs_through_its_points(tmp_path: Path) -> None:
    text = GOOD.replace(
        "line: {to: [-0.10, -0.55, 0.06]}",
        "spline: {through: [[-0.25, -0.50, 0.10], [-0.15, -0.52, 0.16], [-0.10, -0.58, 0.20]]}",
    )
    ex = load_exercise(_write(tmp_path, text))
    first, last = ex.leg_segments[0]
    segs = ex.trajectory.segments[first : last + 1]
    assert len(segs) >= 6 and all(isinstance(s, LineSegment | ArcSegment) for s in segs)
    assert [s.waypoint for s in segs] == [False] * (len(segs) - 1) + [True]
    np.testing.assert_allclose(segs[-1].end, [-0.10, -0.58, 0.20], atol=1e-9)


BAD = [
    ("unreadable", "name: [unclosed\n"),
    ("not_mapping", "- just\n- a list\n"),
    ("unknown_key", GOOD + "colour: red\n"),
    ("missing_key", GOOD.replace("title: Out and back\n", "")),
    ("bad_value", GOOD.replace("speed: 0.1", "speed: 3.0")),
    ("bad_value", GOOD.replace("switch_tol: 0.035", "switch_tol: 0.5")),
    ("bad_vector", GOOD.replace("[-0.35, -0.55, 0.06]", "[-0.35, -0.55]")),
    ("bad_units", GOOD.replace("angle: deg", "angle: rad")),
    ("leg_kind", GOOD.replace("line: {to: start}", "line: {to: start}\n    arc: {angle: 3}")),
    ("duplicate_leg", GOOD.replace("name: back", "name: out")),
    ("degenerate", GOOD.replace("[-0.10, -0.55, 0.06]", "[-0.35, -0.55, 0.06]")),
    ("bad_graph", GOOD + "script: {graph: no_such_graph.yaml}\n"),
    (
        "spline_fit",
        GOOD.replace(
            "line: {to: [-0.10, -0.55, 0.06]}",
            "spline: {through: [[-0.2, -0.55, 0.06], [-0.3, -0.55, 0.0601], "
            "[-0.2, -0.55, 0.06]], tolerance: 0.00001}",  # a cusp: no tangent to follow
        ),
    ),
]


@pytest.mark.parametrize(("kind", "text"), BAD, ids=[f"{k}-{i}" for i, (k, _) in enumerate(BAD)])
def test_each_bad_file_is_refused_naming_its_problem(tmp_path: Path, kind: str, text: str) -> None:
    assert kind in _kinds(tmp_path, text)


def test_every_problem_is_reported_at_once_with_leg_and_line(tmp_path: Path) -> None:
    text = GOOD.replace("speed: 0.1", "speed: -1").replace(
        "line: {to: start}", "line: {to: [1, 2]}\n    wobble: 3"
    )
    with pytest.raises(ExerciseError) as info:
        load_exercise(_write(tmp_path, text))
    kinds = [p.kind for p in info.value.problems]
    assert {"bad_value", "bad_vector", "unknown_key"} <= set(kinds)
    message = str(info.value)
    assert "ex.yaml" in message and "leg 'back'" in message
    assert "line.to (m) must be [x, y, z]" in message and "(line 12)" in message  # its key's line
    assert "unknown key 'wobble'" in message and "(line 13)" in message


def test_an_unknown_key_is_named_with_its_line_and_the_closest_known_one(
    tmp_path: Path,
) -> None:
    """A typo at the top level or inside a leg names the key's own line (not the leg's first)
    and the key it was probably meant to be."""
    text = GOOD.replace("speed: 0.1", "sped: 0.1").replace(
        "  - name: back\n    line: {to: start}", "  - name: back\n    line:\n      too: start"
    )
    with pytest.raises(ExerciseError) as info:
        load_exercise(_write(tmp_path, text))
    lines = str(info.value).splitlines()
    top = next(line for line in lines if "'sped'" in line)
    assert "did you mean 'speed'?" in top and top.endswith("(line 6)")
    leg = next(line for line in lines if "'too'" in line)
    assert "leg 'back'" in leg and "did you mean 'to'?" in leg and leg.endswith("(line 13)")


def test_a_yaml_syntax_error_names_the_file_and_its_line(tmp_path: Path) -> None:
    with pytest.raises(ExerciseError) as info:
        load_exercise(_write(tmp_path, GOOD.replace("title: Out and back", "title: [Out")))
    message = str(info.value)
    assert "<unicode string>" not in message
    assert f'in "{tmp_path / "ex.yaml"}", line 3' in message


def test_a_spline_point_is_named(tmp_path: Path) -> None:
    text = GOOD.replace(
        "line: {to: [-0.10, -0.55, 0.06]}",
        "spline: {through: [[-0.2, -0.5, 0.1], [-0.1, nan, 0.1]]}",
    )
    with pytest.raises(ExerciseError) as info:
        load_exercise(_write(tmp_path, text))
    (p,) = info.value.problems
    assert (p.kind, p.leg, p.point) == ("bad_vector", "out", 1)


def test_problem_kinds_are_many_and_closed() -> None:
    assert len(PROBLEM_KINDS) >= 12
    with pytest.raises(ValueError, match="kind"):
        Problem("nonsense", None, None, "")


def test_exercises_in_code_are_checked_at_construction() -> None:
    start = np.array([-0.35, -0.55, 0.06])
    legs = (Leg("out", "line", end=np.array([-0.1, -0.55, 0.06])),)
    ex = Exercise("in_code", "In code", start, legs)
    assert ex.trajectory.length == pytest.approx(0.25)
    with pytest.raises(ExerciseError, match="duplicate_leg"):
        Exercise("dup", "Dup", start, legs + legs)
    with pytest.raises(ExerciseError, match="speed"):
        Exercise("fast", "Fast", start, legs, speed=1.0)
    with pytest.raises(ExerciseError, match="missing_key"):
        Leg("arc", "arc", center=start)
    with pytest.raises(ExerciseError, match=r"tool\.axis"):
        Leg("line", "line", end=start, tool_turn=0.3)


@pytest.mark.parametrize(
    ("leg", "message"),
    [
        (
            "arc: {center: [-0.2, -0.55, 0.06], axis: [0, 0, 1], angle: 400}",
            "arc.angle must satisfy 0 < |angle| <= 360 deg, got 400",
        ),
        (
            "arc: {center: [-0.2, -0.55, 0.06], axis: [0, 0, 1], angle: 0}",
            "arc.angle must satisfy 0 < |angle| <= 360 deg, got 0",
        ),
        (
            "line: {to: start}\n    tool: {turn: -400}",
            "tool.turn must lie in [-360, 360] deg, got -400",
        ),
    ],
)
def test_an_angle_out_of_its_range_is_named(tmp_path: Path, leg: str, message: str) -> None:
    with pytest.raises(ExerciseError) as info:
        load_exercise(_write(tmp_path, GOOD.replace("line: {to: start}", leg)))
    assert [p.kind for p in info.value.problems] == ["bad_value"]
    assert message in str(info.value)
