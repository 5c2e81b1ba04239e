"""What is checked before a UR moves, and the two steps that prepare a session.

:func:`run_checks` only reads (the dry run stops after it and :func:`plan`); a session then
zeroes the wrist sensor with the arm at rest (:func:`zero_sensor`) and, after the operator
confirms, moves slowly to the exercise's start (:func:`move_to_start`).

| check | passes when |
|---|---|
| ``controller_version`` | PolyScope >= ``min_version`` (e-series: 500 Hz RTDE) |
| ``robot_state`` | no protective or emergency stop, the control script runs |
| ``payload`` | mass and centre of gravity on the robot match the set-up within tolerance |
| ``tcp`` | the TCP offset on the robot matches the set-up |
| ``at_rest`` | the robot reports itself steady and the TCP moves < 1 mm/s |
| ``start_reachable`` | the exercise's start is within ``max_approach`` of the TCP and within the robot's own safety limits |
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from langenv.errors import DeviceError
from langenv.exercise import resolve_exercise
from langenv.live.ur_exercise import ExerciseSpec, exercise_trajectory, start_pose
from langenv.robot.ur.bridge import URRobot
from langenv.robot.ur.config import URConfig

__all__ = ["REST_SPEED", "Check", "move_to_start", "plan", "run_checks", "zero_sensor"]

REST_SPEED = 1e-3
"""TCP speed (m/s) below which the arm counts as at rest."""

ZERO_RESIDUAL = 2.0
"""Largest force (N) the sensor may read at rest right after zeroing."""


@dataclass(frozen=True)
class Check:
    """One preflight check: its name, whether it passed, and what was found."""

    name: str
    ok: bool
    detail: str

    def line(self) -> str:
        """One line for the terminal."""
        return f"  [{'ok' if self.ok else 'FAIL'}] {self.name}: {self.detail}"


def _version(text: str) -> tuple[int, ...]:
    found = re.search(r"([0-9]+(?:\.[0-9]+)+)", text)
    return tuple(int(x) for x in found.group(1).split(".")) if found else ()


def run_checks(robot: URRobot, config: URConfig, exercise: ExerciseSpec = None) -> list[Check]:
    """Read the robot and check it against ``config`` and ``exercise``'s start (a name, a path
    or an :class:`~langenv.exercise.Exercise`; None: the study's); commands nothing."""
    checks = []
    text = robot.controller_version()
    have, need = _version(text), _version(config.min_version)
    checks.append(
        Check(
            "controller_version",
            bool(have) and have >= need,
            f"{text!r} (need >= {config.min_version})",
        )
    )
    state = robot.read()
    bad = [
        what
        for what, on in (
            ("protective stop", state.protective_stop),
            ("emergency stop", state.emergency_stop),
            ("control script not running", not state.program_running),
        )
        if on
    ]
    checks.append(Check("robot_state", not bad, ", ".join(bad) or "no stop, script running"))
    mass, cog = robot.payload()
    d_cog = float(np.linalg.norm(cog - config.payload_cog))
    ok = abs(mass - config.payload_mass) <= config.mass_tolerance and d_cog <= config.cog_tolerance
    checks.append(
        Check(
            "payload",
            ok,
            f"robot {mass:.3f} kg at {np.round(cog, 4).tolist()} m, set-up "
            f"{config.payload_mass:.3f} kg at {config.payload_cog.tolist()} m",
        )
    )
    tcp = robot.tcp_offset()
    d_pos = float(np.linalg.norm(tcp[:3] - config.tcp_offset[:3]))
    d_rot = float(np.linalg.norm(tcp[3:] - config.tcp_offset[3:]))
    checks.append(
        Check(
            "tcp",
            d_pos <= config.tcp_tolerance and d_rot <= math.radians(0.5),
            f"robot {np.round(tcp, 4).tolist()}, set-up {np.round(config.tcp_offset, 4).tolist()}",
        )
    )
    speed = float(np.linalg.norm(state.tcp_velocity[:3]))
    steady = robot.is_steady()
    checks.append(
        Check("at_rest", steady and speed < REST_SPEED, f"steady={steady}, TCP {speed:.4f} m/s")
    )
    target = start_pose(config, state.tcp_pose[3:], exercise)
    gap = float(np.linalg.norm(target[:3] - state.position))
    within = robot.pose_within_limits(target)
    checks.append(
        Check(
            "start_reachable",
            gap <= config.max_approach and within,
            f"start {np.round(target[:3], 4).tolist()} m is {gap * 100:.1f} cm away "
            f"(at most {config.max_approach * 100:.0f} cm), within the robot's limits: {within}",
        )
    )
    return checks


def plan(robot: URRobot, config: URConfig, exercise: ExerciseSpec = None) -> list[str]:
    """What a session of ``exercise`` would do, in order, one line each."""
    state = robot.read()
    target = start_pose(config, state.tcp_pose[3:], exercise)
    gap = float(np.linalg.norm(target[:3] - state.position))
    path = exercise_trajectory(config, exercise)
    name = resolve_exercise(exercise).name
    return [
        "1. zero the wrist force/torque sensor (arm at rest)",
        f"2. after you confirm: moveL to the exercise's start {np.round(target[:3], 4).tolist()} m "
        f"({gap * 100:.1f} cm at {config.approach_speed:g} m/s, about "
        f"{gap / config.approach_speed:.1f} s), orientation held",
        f"3. the session: speedL at {config.frequency:g} Hz along the exercise {name!r} "
        f"({path.length:.3f} m, {len(path.waypoint_s)} legs), speaking through the sound card",
        f"4. on any stop: speedStop at {config.stop_deceleration:g} m/s^2, speech faded out; "
        f"RTDE watchdog at {config.watchdog_hz:g} Hz",
    ]


def zero_sensor(robot: URRobot, settle_periods: int = 50) -> None:
    """Zero the wrist sensor with the arm at rest, then check it reads near 0.

    Raises:
        DeviceError: the arm is moving, or the sensor reads more than ``ZERO_RESIDUAL`` N after.
    """
    state = robot.read()
    speed = float(np.linalg.norm(state.tcp_velocity[:3]))
    if speed >= REST_SPEED or not robot.is_steady():
        raise DeviceError(f"cannot zero the force sensor: the arm moves ({speed:.4f} m/s)")
    robot.zero_ft_sensor()
    worst = 0.0
    for _ in range(settle_periods):
        robot.wait()
        worst = max(worst, float(np.linalg.norm(robot.read().force)))
    if worst > ZERO_RESIDUAL:
        raise DeviceError(
            f"the force sensor reads up to {worst:.1f} N after zeroing (at most {ZERO_RESIDUAL} "
            "N): is someone touching the handle?"
        )


def move_to_start(
    robot: URRobot,
    config: URConfig,
    confirm: Callable[[str], bool],
    exercise: ExerciseSpec = None,
) -> NDArray[np.float64]:
    """After ``confirm(question)`` answers True, moveL slowly to ``exercise``'s start.

    Returns:
        The start pose reached (6,).

    Raises:
        DeviceError: not confirmed, the start too far, or not reached within 2 mm.
    """
    state = robot.read()
    target = start_pose(config, state.tcp_pose[3:], exercise)
    gap = float(np.linalg.norm(target[:3] - state.position))
    if gap > config.max_approach:
        raise DeviceError(
            f"the exercise's start is {gap * 100:.1f} cm away (at most "
            f"{config.max_approach * 100:.0f} cm): bring the arm closer first"
        )
    question = (
        f"Move the arm {gap * 100:.1f} cm to the exercise's start at "
        f"{config.approach_speed:g} m/s? Keep clear of the arm. [y/N] "
    )
    if not confirm(question):
        raise DeviceError("the move to the exercise's start was not confirmed: nothing moved")
    robot.enable()
    try:
        robot.move_linear(target, config.approach_speed, 0.25)
    finally:
        robot.stop()
    reached = robot.read().position
    miss = float(np.linalg.norm(reached - target[:3]))
    if miss > 0.002:
        raise DeviceError(f"the arm stopped {miss * 1e3:.1f} mm from the exercise's start")
    return target
