"""``langctrl robot``: the controller on a real UR (or URSim).

::

    langctrl robot --host 192.168.1.10 --dry-run      # connect, check, print the plan
    langctrl robot --config configs/ur.yaml --log-out session.csv
    langctrl robot --host 127.0.0.1 --fake --dry-run  # against the built-in fake
    langctrl robot --config configs/ur.yaml --exercise hand_to_mouth --dry-run

``--exercise NAME|PATH`` (default: the study's) is loaded and checked
(:func:`~langenv.exercise.check.check_exercise`: reach, joint margins, contacts, speed, script)
before the robot is even connected; a failed check is an error naming every problem.

A dry run connects, reads, runs the preflight checks (:mod:`langenv.live.ur_preflight`) and
prints what a session would do; it commands no motion. A session then zeroes the wrist sensor,
asks before the slow move to the exercise's start, and runs the policy at 500 Hz until the
exercise ends or the first stop; every way out sends ``speedStop``.

Exit codes: 0 done (a dry run whose checks all pass, a session that finished), 1 a check failed
or the session ended on a stop, 2 a usage or connection error (no traceback).
"""

from __future__ import annotations

import argparse
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from langctrl import options
from langenv.errors import LangEnvError

__all__ = ["build_parser", "main", "parse_args"]


def build_parser() -> argparse.ArgumentParser:
    """The command line of ``langctrl robot`` (``python -m langctrl.jobs.robot``)."""
    p = options.job_parser(
        "robot",
        "Run LangCtrl on a UR (or URSim) through ur-rtde: connect, check, then one guided session.",
        options.exercise("anything connects or moves"),
        options.policy(),
        options.overwrite("an existing --log-out or --audio-out file"),
        options.device(),
        options.log_out(),
        options.audio_out(),
    )
    p.add_argument(
        "--host",
        default=None,
        help="the robot's (or URSim's) address; overrides the --config file's (default: that "
        "file's host; give --host, --config or both)",
    )
    p.add_argument(
        "--config",
        type=Path,
        default=None,
        metavar="YAML",
        help="UR set-up YAML in m, kg, deg and s, such as configs/ur.yaml (every key and its "
        "default: langenv/robot/ur/config.py; default: those defaults with --host)",
    )
    p.add_argument("--dry-run", action="store_true", help="connect, check, plan; move nothing")
    p.add_argument("--yes", action="store_true", help="confirm the move to the start (no prompt)")
    p.add_argument(
        "--fake", action="store_true", help="drive the built-in fake UR (a loopback host only)"
    )
    return p


def parse_args(argv: Sequence[str] | None = None) -> argparse.Namespace:
    """Parse the command line."""
    p = build_parser()
    ns = p.parse_args(argv)
    if ns.host is None and ns.config is None:
        p.error("give --host HOST or --config FILE")
    options.check_outputs(p, ns.overwrite, {"--log-out": ns.log_out, "--audio-out": ns.audio_out})
    return ns


def _config(ns: argparse.Namespace) -> Any:
    from langenv.robot.ur.config import URConfig, load_ur_config

    if ns.config is not None:
        return load_ur_config(ns.config, host=ns.host)
    return URConfig(host=ns.host)


def run(
    ns: argparse.Namespace,
    out: Callable[[str], None] = print,
    ask: Callable[[str], str] = input,
) -> int:
    """Connect, check, and (unless a dry run) run one session; returns the exit code."""
    from langenv.live import ur_preflight as preflight
    from langenv.live.ur_exercise import checked_exercise
    from langenv.robot.backends import make_robot

    config = _config(ns)
    exercise = checked_exercise(ns.exercise)  # before anything connects or moves
    if not ns.dry_run and ns.audio_out is None:
        from langenv.live.sinks import check_output_device

        check_output_device(ns.device)  # the sound card too: a session speaks through it
    fake = None
    if ns.fake:
        from langenv.robot.ur.fake_rtde import FakeUR

        fake = FakeUR(config.host).serve()
    try:
        robot: Any = make_robot("ur-fake" if ns.fake else "ur", config=config)
        with robot:
            checks = preflight.run_checks(robot, config, exercise)
            out(f"robot at {config.host}:")
            for check in checks:
                out(check.line())
            passed = all(c.ok for c in checks)
            out(
                ("would do:" if ns.dry_run else "plan:")
                + "\n"
                + "\n".join(preflight.plan(robot, config, exercise))
            )
            if ns.dry_run or not passed:
                if not passed:
                    out("not moving: a check failed")
                return 0 if passed else 1
            return _session(ns, robot, config, exercise, out, ask)
    finally:
        if fake is not None:
            fake.shutdown()


def _session(
    ns: argparse.Namespace,
    robot: Any,
    config: Any,
    exercise: Any,
    out: Callable[[str], None],
    ask: Callable[[str], str],
) -> int:
    from langenv.live import ur_preflight as preflight
    from langenv.live.registry import load_registered_policy
    from langenv.live.robot_loop import RobotLoop
    from langenv.live.sinks import SoundCardSink, WavSink
    from langenv.live.ur_exercise import exercise_trajectory

    policy = load_registered_policy(ns.policy)  # before anything moves

    def make_sink(ring: Any, sr: int) -> Any:
        if ns.audio_out is not None:
            return WavSink(ring, ns.audio_out, sr)
        return SoundCardSink(ring, sr, device=ns.device)

    loop = RobotLoop(
        robot,
        policy,
        trajectory=exercise_trajectory(config, exercise),
        exercise=exercise,
        make_sink=make_sink,
        log_path=ns.log_out,
        acceleration=config.speed_acceleration,
    )
    preflight.zero_sensor(robot)
    out("force sensor zeroed")
    preflight.move_to_start(
        robot, config, lambda q: ns.yes or ask(q).strip().lower() in ("y", "yes"), exercise
    )
    out("at the exercise's start; session running (Ctrl-C stops the arm)")
    report = loop.run()
    out(report.summary())
    return 0 if report.stop is None else 1


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point; returns the exit code."""
    ns = parse_args(argv)
    try:
        return run(ns)
    except LangEnvError as exc:
        return options.fail("robot", exc)
    except KeyboardInterrupt:
        return options.stopped("robot")


if __name__ == "__main__":
    raise SystemExit(main())
