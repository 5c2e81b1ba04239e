"""Loops: legs that end where they start (a circle, the lobes of a figure eight) check and run.

The data: ``tests/data/exercises/circle.yaml`` (one arc leg of 360 deg) and ``figure_eight.yaml``
(two spline lobes, each ending where it starts), written as a new user would. The guide's rule
(``langenv/control/guide.py``, "Loops"): a leg that comes back near its end has a gate on its
final approach; every other leg's gate is its start, so the switch there is the lab's, to the
bit (no shipped leg returns: checked here; the pinned episodes hold it too).
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import pytest

import langenv
from bench.etc_agreement import random_pace, random_resistance
from langctrl.jobs.exercise import main as exercise_cli
from langenv.control.admittance import AdmittanceParams, VariableAdmittance
from langenv.control.cooperation import CooperationFilter
from langenv.control.guide import GATE_REACH, Guide
from langenv.control.motion_etc import FastETC, reference_etc
from langenv.control.trajectory import (
    MAX_ARC_ANGLE,
    ArcSegment,
    LineSegment,
    Trajectory,
    default_exercise,
    split_arc,
)
from langenv.control.trajectory_kernels import closest as compiled_closest
from langenv.control.virtual_loop import simulate_virtual
from langenv.env import LangCtrlEnv
from langenv.errors import ExerciseError
from langenv.exercise import SHIPPED_EXERCISES, Exercise, load_exercise, resolve_exercise
from langenv.exercise.check import check_exercise
from langenv.exercise.path_checks import path_problems
from langenv.motion.tick import GuidedArm
from langenv.robot.arm import Arm
from langenv.robot.force_sensor import ForceSensor
from langenv.robot.safety import SafetyLimits
from policies import load_policy

DATA = Path(__file__).parent / "data" / "exercises"
LOOPS = ("circle", "figure_eight")
NOMINAL = {"circle": 8.49, "figure_eight": 16.44}
"""Simulated motion times at cooperation 1 (s), as measured when the loops were added."""


def _loop(name: str) -> Exercise:
    return load_exercise(DATA / f"{name}.yaml")


def _guide(ex: Exercise) -> Guide:
    return Guide(ex.trajectory, ex.admittance())


# --------------------------------------------------------------------------- the rule


@pytest.mark.parametrize("name", sorted(SHIPPED_EXERCISES))
def test_no_shipped_leg_returns_so_their_switch_is_the_labs(name: str) -> None:
    """Every gate of a shipped exercise is its leg's start, where the closest point's window
    begins: ``s >= gate`` always holds there and the switch is the pose test alone."""
    ex = resolve_exercise(name)
    guide = _guide(ex)
    for k in range(guide.n_legs):
        assert guide.gate(k) == ex.leg_span(k)[0] and not guide.returns(k), ex.leg_names[k]
    study = Guide(default_exercise(), AdmittanceParams())
    assert all(study.gate(k) == study._starts[k] for k in range(study.n_legs))


@pytest.mark.parametrize("name", LOOPS)
def test_a_loop_leg_returns_and_its_gate_begins_its_final_approach(name: str) -> None:
    ex = _loop(name)
    guide, traj = _guide(ex), ex.trajectory
    reach = GATE_REACH * ex.switch_tol
    for k in range(guide.n_legs):
        a, b = ex.leg_span(k)
        gate, end = guide.gate(k), traj.position(b)
        assert guide.returns(k) and a < gate < b
        assert np.linalg.norm(traj.position(gate) - end) >= reach  # still that far at the gate
        after = np.linspace(gate + 0.002, b, 50)  # then within reach of the end, to the end
        assert all(np.linalg.norm(traj.position(s) - end) < reach for s in after)
        assert np.linalg.norm(traj.position(a) - end) < 1e-9  # it ends where it starts


def test_the_switch_waits_until_the_hand_has_gone_round() -> None:
    ex = _loop("circle")
    guide, traj = _guide(ex), ex.trajectory
    start = traj.position(0.0)
    st = guide.initial_state()
    guide.update(st, start)
    assert (st.leg, st.done) == (0, False)  # at the start of the loop: not done
    # the lab's pose test alone (every gate at its leg's start) takes it as done at once: the
    # issue's "nominal motion time 0.0 s"
    old = Guide(traj, ex.admittance())
    old._gate = list(old._starts)
    st_old = old.initial_state()
    old.update(st_old, start)
    assert st_old.done
    # round the loop: done within switch_tol of its end, as on any leg
    near = traj.length - 0.5 * ex.switch_tol
    st.s = near - 0.01
    guide.update(st, traj.position(near))
    assert st.done and st.s == traj.length


@pytest.mark.parametrize("name", LOOPS)
def test_the_closest_point_stays_local_at_a_loops_start_and_end(name: str) -> None:
    """Behind a loop's start the closest point stays at the start (it does not jump to the
    loop's end, as near to the hand); past the end it stays at the end (not back to the start)."""
    ex = _loop(name)
    traj = ex.trajectory
    path = traj.packed()
    for k in range(len(ex.legs)):
        a, b = ex.leg_span(k)
        behind = traj.position(a) - 0.004 * traj.tangent(a)
        past = traj.position(b) + 0.004 * traj.tangent(b - 1e-9)
        for x, s_prev, want in ((behind, a, a), (past, b - 0.01, b)):
            s = traj.closest(x, s_prev, a, b)
            assert s == pytest.approx(want, abs=1e-3)
            assert compiled_closest(path, *x.tolist(), s_prev, a, b) == s


def test_arcs_over_half_a_turn_are_kept_as_pieces() -> None:
    c, z = np.zeros(3), np.array([0.0, 0.0, 1.0])
    start = np.array([0.1, 0.0, 0.0])
    full = ArcSegment(c, z, start, 2.0 * math.pi, waypoint=True, turn=0.5)
    pieces = split_arc(full)
    assert len(pieces) == 2 and all(abs(p.angle) <= MAX_ARC_ANGLE for p in pieces)
    assert [p.waypoint for p in pieces] == [False, True]
    assert sum(p.turn for p in pieces) == pytest.approx(0.5)  # type: ignore[misc]
    np.testing.assert_allclose(pieces[-1].end, start, atol=1e-15)
    assert len(split_arc(ArcSegment(c, z, start, -1.5 * math.pi))) == 2
    half = ArcSegment(c, z, start, math.pi)
    assert split_arc(half)[0] is half and len(split_arc(half)) == 1
    # a Trajectory keeps them so: one full circle, and the search stays local at its start
    tr = Trajectory([full])
    assert len(tr.segments) == 2 and tr.length == pytest.approx(0.2 * math.pi)
    behind = np.array([0.1, -0.003, 0.0])  # just behind the start
    assert tr.closest(behind, 0.0) == 0.0  # one full-circle arc would have projected to its end
    # an exercise's arc leg of 360 deg: its span covers both pieces
    ex = _loop("circle")
    assert ex.leg_segments == ((0, 1),) and ex.trajectory.length == pytest.approx(0.2 * math.pi)
    # a line and half-turn arcs are left alone (the shipped paths are unchanged)
    line = LineSegment(np.zeros(3), np.ones(3), True)
    assert Trajectory([line]).segments == (line,)


# --------------------------------------------------------------------------- check and ETC


@pytest.mark.parametrize("name", LOOPS)
def test_the_loop_exercises_pass_their_checks(name: str) -> None:
    report = check_exercise(_loop(name))
    assert report.ok and report.run.time is not None
    assert report.run.time == pytest.approx(NOMINAL[name], abs=0.02)
    assert abs(report.run.etc - report.run.time) < 0.02  # the whole loop counted from the start
    assert exercise_cli(["check", str(DATA / f"{name}.yaml")]) == 0


@pytest.mark.parametrize("name", LOOPS)
def test_fast_etc_agrees_with_the_reference_on_loops(name: str) -> None:
    ex = _loop(name)
    params = ex.admittance()
    guide, adm = _guide(ex), VariableAdmittance(params)
    fast = FastETC(guide, adm)
    nominal = simulate_virtual(ex.trajectory, params)
    assert nominal.done_time is not None
    # t_x at the start counts the whole exercise (not 0: the loop is not taken as done)
    assert reference_etc(guide, adm, guide.initial_state(), ex.start, np.zeros(3)) == (
        pytest.approx(nominal.done_time)
    )
    assert fast.nominal() == pytest.approx(nominal.done_time, abs=0.02)
    for i in range(0, len(nominal.t) - 1, 200):
        st, x, v, w = nominal.guide_state(i), nominal.x[i], nominal.v_ref[i], nominal.v[i]
        assert fast.etc(st, x, v, w) == pytest.approx(nominal.done_time - nominal.t[i], abs=0.02)
    # random paces and resisting users (pushing up to twice the guide's force)
    rng = np.random.default_rng(7)
    rel = []
    for _ in range(3):
        run = simulate_virtual(
            ex.trajectory,
            params,
            p=random_pace(rng),
            force=random_resistance(rng, f_max=2.0 * params.propel_force),
        )
        assert run.done_time is not None
        for i in np.linspace(0, len(run.t) - 2, 8).astype(int).tolist():
            st, x, v, w = run.guide_state(i), run.x[i], run.v_ref[i], run.v[i]
            ref = reference_etc(guide, adm, st, x, v, w)
            rel.append(abs(fast.etc(st, x, v, w) - ref) / max(ref, 0.1))
    assert max(rel) <= 0.02 and float(np.mean(rel)) <= 0.01  # as on the study's exercise


# --------------------------------------------------------------------------- running


def _arm_pair(ex: Exercise) -> tuple[GuidedArm, GuidedArm]:
    def make(compiled: bool) -> GuidedArm:
        return GuidedArm(
            Arm(),
            ex.trajectory,
            ex.admittance(),
            ForceSensor(),
            CooperationFilter(),
            SafetyLimits(),
            compiled=compiled,
        )

    fast, ref = make(True), make(False)
    assert fast.compiled and not ref.compiled
    return fast, ref


def _observed(m: GuidedArm) -> tuple[Any, ...]:
    st = m.state
    vectors = np.concatenate([m.v_ref, m.v_cmd, m.tangent(), m.arm.data.qpos, m.arm.data.qvel])
    scalars = (st.s, st.leg, st.done, m.t_x, m.time, m.t_motion_end, m.path_deviation)
    return (*scalars, m.hand_speed, m.cooperation, vectors.tobytes())


@pytest.mark.portable
@pytest.mark.parametrize(("name", "ticks"), [("circle", 4800), ("figure_eight", 4600)])
def test_the_compiled_tick_equals_the_python_one_round_a_loop(name: str, ticks: int) -> None:
    """Pushes along and against the guide, a varying pace, sensor noise: every observable equal
    after every tick, through the figure eight's switch between lobes and the circle's end."""
    fast, ref = _arm_pair(_loop(name))
    fast.reset()
    ref.reset()
    assert fast.t_x == ref.t_x and fast.t_x > 5.0  # the whole loop ahead
    gen = np.random.default_rng(5)
    rng_a, rng_b = np.random.default_rng(3), np.random.default_rng(3)
    for i in range(ticks):
        push = 4.0 if (i // 700) % 2 else -2.0
        f = gen.normal(0.0, 3.0, 3) + push * fast.tangent()
        p, p_dot = 1.0 + 0.3 * math.sin(i / 300), 0.5 * math.cos(i / 300)
        fast.tick(f, p, p_dot, rng_a)
        ref.tick(f, p, p_dot, rng_b)
        a, b = _observed(fast), _observed(ref)
        assert a == b, f"tick {i}: compiled {a[:10]} != Python {b[:10]}"
    assert fast.state.leg >= 1  # the switch between the lobes, or the circle's end, crossed
    assert fast.motion_done == (name == "circle")


def _episode(env: gym.Env, policy: Any, seed: int) -> tuple[dict[str, Any], dict[str, Any]]:
    obs, first = env.reset(seed=seed)
    for _ in range(5000):
        obs, _, term, trunc, info = env.step(policy.act(obs))
        if term or trunc:
            assert term and not trunc
            return first, info
    raise AssertionError("episode did not end")


@pytest.mark.parametrize("name", LOOPS)
def test_loops_run_in_the_env_with_ac_and_lc(name: str) -> None:
    for kind in ("ac", "lc"):
        env = gym.make(langenv.ENV_ID, exercise=str(DATA / f"{name}.yaml"), decision_hz=25)
        policy = load_policy(kind)
        first, last = _episode(env, policy, seed=1)
        assert first["t_x"] == pytest.approx(NOMINAL[name], abs=0.05)  # the whole loop ahead
        assert last["motion_done"] and last["speech_done"] and last["safety_stop"] is None
        assert last["t_motion"] is not None and last["t_motion"] > 0.8 * NOMINAL[name]
        assert last["path_deviation"] < 0.05


@pytest.mark.portable
def test_the_envs_compiled_steps_equal_its_python_steps_on_a_figure_eight() -> None:
    kw = {"exercise": str(DATA / "figure_eight.yaml"), "decision_hz": 25}
    fast, ref = LangCtrlEnv(**kw), LangCtrlEnv(**kw)  # type: ignore[arg-type]
    ref._steps = None  # the Python ticks
    oa, _ = fast.reset(seed=4)
    ob, _ = ref.reset(seed=4)
    assert oa.tobytes() == ob.tobytes()
    act = np.zeros(fast.action_space.shape, dtype=np.float32)
    for k in range(3000):
        a, b = fast.step(act), ref.step(act)
        assert a[0].tobytes() == b[0].tobytes() and a[1:] == b[1:], f"step {k}"
        if a[2]:
            break
    assert fast.motion.motion_done and ref.motion.motion_done


# --------------------------------------------------------------------------- what cannot run

HEAD = """\
# A new user's loop.
name: my_loop
title: My loop
start: [-0.30, -0.55, 0.06]
speed: {speed}
switch_tol: 0.035
legs:
  - name: round
"""
SMALL_CIRCLE = "    arc: {center: [-0.30, -0.52, 0.06], axis: [0, 0, 1], angle: 360}\n"
CIRCLE = "    arc: {center: [-0.30, -0.45, 0.06], axis: [0, 0, 1], angle: 360}\n"
STILL = "    tool: {turn: 0}\n"


def _file(tmp_path: Path, legs: str, speed: float = 0.06) -> Path:
    path = tmp_path / "my_loop.yaml"
    path.write_text(HEAD.format(speed=speed) + legs + SCRIPT)
    return path


# the study's words, unmarked (the default script marks the study's exercise's legs, which a
# loop lacks: exercise check refuses it, unknown_leg)
SCRIPT = "script: {graph: study, single: lc-noap}\n"


def test_a_loop_too_small_to_go_round_is_a_loop_problem_saying_why(tmp_path: Path) -> None:
    ex = load_exercise(_file(tmp_path, SMALL_CIRCLE + STILL, speed=0.04))
    problems, run = path_problems(ex)
    assert [p.kind for p in problems] == ["loop"]  # not "nominal motion time 0.0 s"
    detail = problems[0].detail
    assert problems[0].leg == "round" and "as done at its start" in detail
    assert "never goes farther than 0.060 m" in detail and "0.070 m" in detail
    assert "switch_tol to at most 0.029" in detail  # what would let it run
    assert run.time is not None and run.time < 0.01  # what the guide would do
    # and at that switch_tol it runs
    fixed = load_exercise(_file(tmp_path, SMALL_CIRCLE + STILL, speed=0.04))
    fixed = Exercise(fixed.name, fixed.title, fixed.start, fixed.legs, 0.04, 0.029)
    problems, run = path_problems(fixed)
    assert not problems and run.time is not None and run.time > 4.0


@pytest.mark.parametrize(
    ("legs", "kind", "words"),
    [
        (  # out and back along itself
            "    spline: {through: [[-0.20, -0.55, 0.06], [-0.30, -0.55, 0.06]]}\n",
            "loop",
            "goes out and back along itself",
        ),
        ("    spline: {through: [[-0.30, -0.55, 0.06]]}\n", "loop", "has no length"),
        ("    line: {to: start}\n", "degenerate", "ends where it starts"),
    ],
    ids=["spline-out-and-back", "spline-to-itself", "line-to-itself"],
)
def test_a_leg_with_no_way_round_is_refused_at_load(
    tmp_path: Path, legs: str, kind: str, words: str
) -> None:
    with pytest.raises(ExerciseError) as info:
        load_exercise(_file(tmp_path, legs))
    (problem,) = info.value.problems
    assert problem.kind == kind and problem.leg == "round" and words in problem.detail
    assert "(line 8)" in problem.detail and "my_loop.yaml" in str(info.value)


def test_a_loop_too_tight_for_its_speed_names_the_speed_that_works(tmp_path: Path) -> None:
    ex = load_exercise(_file(tmp_path, CIRCLE + STILL, speed=0.12))
    problems, _ = path_problems(ex)
    bends = [p for p in problems if p.kind == "curvature"]
    assert len(bends) == 1 and bends[0].leg == "round"  # one per leg, at its tightest bend
    assert "a speed of at most 0.083 m/s" in bends[0].detail
    slower = load_exercise(_file(tmp_path, CIRCLE + STILL, speed=0.083))
    assert not path_problems(slower)[0]


def test_a_circle_whose_tool_turns_round_is_told_how_to_keep_it_still(tmp_path: Path) -> None:
    ex = load_exercise(_file(tmp_path, CIRCLE, speed=0.08))  # an arc's tool turns with it
    with pytest.raises(ExerciseError) as info:
        check_exercise(ex)
    hints = [p for p in info.value.problems if "tool: {turn: 0} keeps it still" in p.detail]
    assert hints and {p.kind for p in hints} <= {"unreachable", "joint_margin"}
    assert check_exercise(load_exercise(_file(tmp_path, CIRCLE + STILL, speed=0.08))).ok


def test_the_command_line_names_a_bad_loop_without_a_traceback(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    bad = _file(tmp_path, SMALL_CIRCLE + STILL, speed=0.04)
    assert exercise_cli(["check", str(bad)]) == 1
    err = capsys.readouterr().err
    assert f"{bad}: leg 'round': loop: the guide would take" in err
    assert "Traceback" not in err and "REFUSED (1 problem)" in err


def test_the_renderer_draws_a_figure_eight(tmp_path: Path, offscreen_gl: None) -> None:
    out = tmp_path / "f8.png"
    args = ["render", str(DATA / "figure_eight.yaml"), "--out", str(out), "--width", "320"]
    assert exercise_cli(args) == 0
    assert out.stat().st_size > 1000


def test_the_ur_bridge_runs_a_loop_round_to_its_end(tmp_path: Path) -> None:
    """The robot loop (the Python guide over the fake ur-rtde), the exercise shifted by the
    lab's origin: the session goes round the circle and ends at its end, not at its start."""
    from langenv.live.registry import load_registered_policy
    from langenv.live.robot_loop import RobotLoop
    from langenv.live.ur_exercise import exercise_trajectory
    from langenv.live.ur_preflight import move_to_start, zero_sensor
    from langenv.robot.ur import fake_rtde
    from langenv.robot.ur.bridge import URRobot
    from langenv.robot.ur.config import URConfig

    ex = _loop("circle")
    host = "127.0.0.1"
    cfg = URConfig(host=host, exercise_origin=(0.01, 0.0, 0.0))
    trajectory = exercise_trajectory(cfg, ex)
    assert Guide(trajectory, ex.admittance()).returns(0)  # still a loop where the lab puts it
    with fake_rtde.FakeUR(host) as ur:
        robot = URRobot(cfg, backend=fake_rtde)
        zero_sensor(robot)
        move_to_start(robot, cfg, lambda q: True, ex)
        loop = RobotLoop(
            robot,
            load_registered_policy("ac"),
            trajectory=trajectory,
            exercise=ex,
            log_path=tmp_path / "session.csv",
        )
        report = loop.run()
        robot.close()
    assert report.stop is None and loop.env.motion.motion_done
    assert 0.9 * NOMINAL["circle"] < report.duration_s < 2.0 * NOMINAL["circle"]
    went = loop.env.motion.state
    assert went.leg == 1 and went.s == pytest.approx(trajectory.length)
    end = trajectory.position(trajectory.length)  # the circle's end: its start, where the lab is
    np.testing.assert_allclose(end, ex.start + np.array([0.01, 0.0, 0.0]), atol=1e-9)
    assert np.linalg.norm(ur.pose[:3] - end) < ex.switch_tol + 0.02  # round, braked near the end
