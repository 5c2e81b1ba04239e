"""Checks before motion: the shipped exercises pass, unsafe ones are refused with leg and reason."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from langenv.errors import ExerciseError
from langenv.exercise import SHIPPED_EXERCISES, Exercise, Leg, resolve_exercise
from langenv.exercise.check import check_exercise, exercise_problems
from langenv.exercise.reach import JOINT_MARGIN, MIN_SIGMA, _Contacts
from langenv.robot.arm import UR5_XML, Arm

START = np.array([-0.35, -0.55, 0.06])
Z = np.array([0.0, 0.0, 1.0])


def _line(name: str, end: object, **kw: object) -> Leg:
    return Leg(name, "line", end=np.asarray(end, float), **kw)  # type: ignore[arg-type]


def _ex(*legs: Leg, speed: float = 0.125, switch_tol: float = 0.035) -> Exercise:
    """A crafted exercise; it speaks the study's graph (unmarked: the default graph's @leg marks
    name the study's legs, which a crafted exercise lacks)."""
    return Exercise(
        "crafted", "Crafted", START, legs, speed=speed, switch_tol=switch_tol, graph="study"
    )


def _kinds(ex: Exercise, model: Path | None = None) -> dict[str, set[str | None]]:
    """Problem kind -> the legs it names."""
    out: dict[str, set[str | None]] = {}
    for p in exercise_problems(ex, model).problems:
        out.setdefault(p.kind, set()).add(p.leg)
    return out


@pytest.mark.parametrize("name", sorted(SHIPPED_EXERCISES))
def test_every_shipped_exercise_passes_its_checks(name: str) -> None:
    report = check_exercise(resolve_exercise(name))
    assert report.ok
    assert report.run.time is not None and 4.0 < report.run.time < 40.0
    assert report.reach.min_sigma >= MIN_SIGMA and report.reach.min_joint_margin >= JOINT_MARGIN
    assert abs(report.run.etc - report.run.time) < 0.4  # the fast ETC agrees with the run
    assert name in report.summary()


def test_an_unreachable_point_is_refused_naming_leg_and_point() -> None:
    ex = _ex(_line("out", [-0.35, -1.0, 0.06]), _line("back", START))
    with pytest.raises(ExerciseError) as info:
        check_exercise(ex)
    unreachable = [p for p in info.value.problems if p.kind == "unreachable"]
    assert unreachable and unreachable[0].leg == "out" and unreachable[0].point is not None
    assert "not reached" in unreachable[0].detail
    assert "singular" in {p.kind for p in info.value.problems}  # on the way there


def test_the_handle_in_the_table_is_a_collision() -> None:
    kinds = _kinds(_ex(_line("down", [-0.35, -0.30, 0.0]), _line("up", START)))
    assert set(kinds) == {"collision"} and "down" in kinds["collision"]


def test_near_the_base_axis_is_singular_and_self_colliding() -> None:
    kinds = _kinds(_ex(_line("in", [-0.03, -0.10, 0.15]), _line("out", START)))
    assert "in" in kinds["singular"] and "in" in kinds["collision"]


def test_self_contacts_are_seen_and_none_at_home() -> None:
    arm = Arm()
    contacts = _Contacts(arm.path, arm.data.qpos.copy())
    assert not contacts.ignored  # nothing touches at the home pose
    folded = np.array([0.861, -1.446, -2.884, -3.038, 1.968, 2.593])  # wrist onto upper arm
    pairs = {pair for pair, dist in contacts.contacts(folded) if dist < 0.0}
    assert ("upper_arm_collision", "wrist_2_collision") in pairs


def test_a_joint_near_its_limit_is_refused(tmp_path: Path) -> None:
    """The path takes the elbow from 1.64 to 1.93 rad: with a range of +-2 rad it stays in
    reach, 0.07 rad from the end; with +-1.6 rad the arm cannot reach it, and says why."""
    legs = (_line("out", [-0.10, -0.55, 0.06]), _line("back", START))
    for limit, kind in (("2.0", "joint_margin"), ("1.7", "unreachable")):
        xml = UR5_XML.read_text().replace(
            '<joint name="elbow"/>', f'<joint name="elbow" range="-{limit} {limit}"/>'
        )
        model = tmp_path / "ur5_narrow.xml"
        model.write_text(xml)
        problems = exercise_problems(_ex(*legs), model).problems
        assert kind in {p.kind for p in problems}
        assert any("'elbow'" in p.detail for p in problems if p.kind == kind)


def test_an_unreachable_stretch_is_one_problem_along_the_leg() -> None:
    """Out of reach from 0.30 m along the way out to 0.35 m along the way back: one problem,
    said in metres along the leg (not an internal sample index), and nothing of the arm's
    meaningless poses there (joint limits, contacts), nor of the reachable start."""
    ex = _ex(_line("reach", [-0.35, -1.2, 0.06]), _line("home", START))
    problems = exercise_problems(ex).problems
    (far,) = [p for p in problems if p.kind == "unreachable"]
    assert far.leg == "reach" and far.at == pytest.approx(0.30, abs=0.011)
    assert "0.70 m of the path" in far.detail and "along leg 'home'" in far.detail
    assert {p.kind for p in problems} == {"unreachable", "singular"}  # on the way there
    assert all("m along it" in str(p) and "point " not in str(p) for p in problems)


def test_a_bend_too_tight_for_the_speed_is_refused() -> None:
    c = np.array([-0.35, -0.50, 0.06])
    ex = _ex(
        Leg("round", "arc", center=c, axis=Z, angle=math.pi),
        Leg("back", "arc", center=c, axis=Z, angle=-math.pi),
        switch_tol=0.1,
    )
    kinds = _kinds(ex)
    assert kinds["curvature"] == {"round", "back"}
    assert "path_error" in kinds and "etc" in kinds  # the guided run leaves the path


def test_a_fast_corner_leaves_the_path() -> None:
    ex = _ex(
        _line("out", [-0.05, -0.55, 0.06]),
        _line("side", [-0.05, -0.25, 0.06]),
        _line("back", START),
        speed=0.25,
    )
    assert "path_error" in _kinds(ex)


def test_short_legs_too_short_a_motion_and_a_missed_waypoint() -> None:
    short = _kinds(_ex(_line("out", [-0.30, -0.55, 0.06]), _line("back", START)))
    assert short["short_leg"] == {"out", "back"} and "duration" in short
    arc = Leg(
        "turn",
        "arc",
        center=np.array([-0.10, -0.45, 0.06]),
        axis=Z,
        angle=math.radians(40),
        waypoint=np.array([0.0, -0.45, 0.06]),
    )
    assert _kinds(_ex(_line("out", [-0.10, -0.55, 0.06]), arc))["gap"] == {"turn"}


def test_a_graph_that_does_not_load_is_refused(tmp_path: Path) -> None:
    graph = tmp_path / "g.yaml"
    graph.write_text("start: a\nphrases:\n  a: {text: hi, next: [b]}\n")  # b unknown
    ex = Exercise(
        "g",
        "G",
        START,
        (_line("out", [-0.05, -0.55, 0.06]), _line("back", START)),
        graph=str(graph),
    )
    assert "bad_graph" in _kinds(ex)
