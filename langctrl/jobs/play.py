"""``langctrl play``: try the controller live, as the person it guides.

With a display, MuJoCo's viewer opens on the arm: double-click the handle, then Ctrl + right-drag
to push on it (your drag is the person's force, through the same sensor and deadband); the robot
speaks through the sound card in real time, slowing, speeding and rewording as you resist, with
the phrase and the paces shown on screen::

    langctrl play                          # LC, you are the person
    langctrl play --policy ppo:models/ppo_speech.zip
    langctrl play --user synthetic --audio-out talk.wav   # watch a simulated person
    langctrl play --exercise hand_to_mouth  # another exercise (checked first)

Headless (tests, servers): the same real-time loop with no window and no sound card, the audio
written to a WAV at the sound card's pace; it prints one summary line (late ticks, underruns)::

    langctrl play --headless --seconds 10 --audio-out out/live.wav

Through the robot-IO seam (:mod:`langenv.robot.io`) the same session runs on a robot from
:data:`~langenv.robot.backends.ROBOT_BACKENDS` (:class:`~langenv.live.robot_loop.RobotLoop`,
one session, the simulated person pushing the simulated robot); a real UR has its own command,
``langctrl robot``::

    langctrl play --robot mujoco --headless --seconds 30 --audio-out out/live.wav \
        --log-out out/session.csv

Policies are found by name through the ``langctrl.policies`` entry points
(:mod:`langenv.live.registry`).
"""

from __future__ import annotations

import argparse
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from langctrl import options
from langenv.errors import LangEnvError

__all__ = ["build_parser", "main", "parse_args"]


def build_parser() -> argparse.ArgumentParser:
    """The command line of ``langctrl play`` (``python -m langctrl.jobs.play``)."""
    p = options.job_parser(
        "play",
        "Run LangCtrl live: you drag the handle, the robot talks you through it.",
        options.exercise("anything moves"),
        options.policy(),
        options.seed(of="the first session"),
        options.overwrite("an existing --audio-out, --trace-out or --log-out file"),
        options.device(),
        options.audio_out("; headless: required"),
        options.log_out(needs="--robot"),
    )
    p.add_argument(
        "--graph",
        "--phrase-graph",
        dest="phrase_graph",
        default=None,
        metavar="GRAPH",
        help="phrase graph for a policy that chooses phrases (lc, ppo...): a YAML file or a "
        "shipped graph such as 'study' (default: the exercise's script; AC and LC-noAP always "
        "say its one wording)",
    )
    p.add_argument(
        "--user",
        default=None,
        help="the person: drag (you, in the viewer), synthetic or replay:CSV (default: drag in "
        "the viewer, synthetic headless)",
    )
    p.add_argument("--headless", action="store_true", help="no window, no sound card")
    p.add_argument(
        "--seconds",
        type=float,
        default=None,
        help="stop after this many seconds, > 0 (default: run until closed; headless: required)",
    )
    p.add_argument(
        "--trace-out",
        type=Path,
        default=None,
        metavar="CSV",
        help="write one CSV row per step: session, t (s), p, a, cooperation, em (s), the force "
        "fx, fy, fz (N), "
        "phrase (default: none)",
    )
    p.add_argument(
        "--robot",
        default=None,
        metavar="BACKEND",
        help="run one session through the robot-IO seam on a simulated robot: mujoco or "
        "ur-fake, headless (default: none; a real UR: langctrl robot)",
    )
    return p


def parse_args(argv: Sequence[str] | None = None) -> argparse.Namespace:
    """Parse the command line."""
    p = build_parser()
    ns = p.parse_args(argv)
    if ns.robot is not None:
        if ns.robot not in ("mujoco", "ur-fake"):
            p.error(
                f"--robot must be mujoco or ur-fake, got {ns.robot!r} (a real UR: python -m "
                "langenv.robot.ur --host HOST)"
            )
        if not ns.headless:
            p.error("--robot needs --headless")
        if ns.trace_out is not None:
            p.error("--robot writes the session CSV with --log-out, not --trace-out")
    if ns.log_out is not None and ns.robot is None:
        p.error("--log-out needs --robot")
    if ns.headless and (ns.seconds is None or ns.audio_out is None):
        p.error("--headless needs --seconds N and --audio-out X.wav")
    if ns.seconds is not None and not ns.seconds > 0:
        p.error(f"--seconds must be > 0, got {ns.seconds}")
    outputs = {"--audio-out": ns.audio_out, "--trace-out": ns.trace_out, "--log-out": ns.log_out}
    options.check_outputs(p, ns.overwrite, outputs)
    if ns.user is None:
        ns.user = "synthetic" if ns.headless else "drag"
    if ns.headless and ns.user == "drag":
        p.error("--user drag needs the viewer (drop --headless)")
    if ns.user not in ("drag", "synthetic") and not ns.user.startswith("replay:"):
        p.error(f"--user must be drag, synthetic or replay:CSV, got {ns.user!r}")
    return ns


def _make_env(ns: argparse.Namespace, policy: Any, user: Any) -> Any:
    import gymnasium as gym

    import langenv

    spoken = _speak(ns, policy)  # before env_kwargs: it may fit a learned model to the graph
    kwargs: dict[str, Any] = dict(policy.env_kwargs)
    if user is not None:
        kwargs["users"] = user
    elif ns.user == "synthetic":
        kwargs["users"] = "synthetic"
    else:
        kwargs.update(users="replay", session=ns.user.removeprefix("replay:"))
    hz = int(policy.decision_hz)
    if ns.exercise is not None:
        from langenv.exercise import resolve_exercise

        kwargs["exercise"] = resolve_exercise(ns.exercise)
    return gym.make(
        langenv.ENV_ID,
        phrase_graph=spoken.ref,
        decision_hz=hz,
        max_seconds=120.0,
        **kwargs,
    )


def _speak(ns: argparse.Namespace, policy: Any) -> Any:
    """The graph ``policy`` speaks on ``--exercise`` (:func:`langenv.exercise.script.speak`):
    ``--graph`` for a policy that chooses phrases; for AC and LC-noAP a ConfigError."""
    from langenv.exercise.script import graph_role, speak, spoken_graph

    if ns.phrase_graph is not None:
        spoken_graph(graph_role(policy), ns.exercise, ns.phrase_graph)  # refuses a one-wording one
    return speak(policy, ns.exercise, ns.phrase_graph)


def run_robot(ns: argparse.Namespace) -> str:
    """One session through the robot-IO seam on a simulated robot; returns the summary line."""
    from langenv.live.registry import load_registered_policy
    from langenv.live.robot_loop import RobotLoop
    from langenv.live.sinks import WavSink
    from langenv.users import ReplayUser, SyntheticUser

    policy = load_registered_policy(ns.policy)
    out = ns.audio_out
    fake = None
    if ns.robot == "mujoco":
        from langenv.robot.sim_io import MujocoRobot

        robot: Any = MujocoRobot(realtime=True, seed=ns.seed)
    else:
        from langenv.robot.ur import fake_rtde
        from langenv.robot.ur.bridge import URRobot
        from langenv.robot.ur.config import URConfig

        fake = fake_rtde.FakeUR("127.0.0.1", realtime=True, seed=ns.seed).serve()
        robot = URRobot(URConfig(host="127.0.0.1"), backend=fake_rtde)
    try:
        with robot:
            loop = RobotLoop(
                robot,
                policy,
                exercise=ns.exercise,
                graph=ns.phrase_graph,
                make_sink=lambda ring, sr: WavSink(ring, out, sr),
                log_path=ns.log_out,
                max_seconds=ns.seconds,
                seed=ns.seed,
            )
            start = loop.env.motion.trajectory.position(0.0)
            if fake is not None:
                fake.pose[:3] = start
            else:
                robot.arm.reset(start)
            user = (
                SyntheticUser()
                if ns.user == "synthetic"
                else ReplayUser.from_csv(ns.user.removeprefix("replay:"))
            )
            person = loop.simulated_person(user)
            if fake is not None:
                fake.person = person
            else:
                robot.person = person
            report = loop.run()
    finally:
        if fake is not None:
            fake.shutdown()
    return f"play: {ns.policy} on {ns.robot}, user {ns.user}: {report.summary()}"


def run(ns: argparse.Namespace) -> str:
    """Build everything, run the loop, return the summary line."""
    if ns.robot is not None:
        return run_robot(ns)
    from langenv.live.drag import DragUser
    from langenv.live.loop import LiveHooks, RealTimeLoop
    from langenv.live.registry import load_registered_policy
    from langenv.live.sinks import SoundCardSink, WavSink

    hooks: LiveHooks = LiveHooks()
    if not ns.headless:
        from langenv.live.viewer import check_display

        check_display()  # before anything slow
    if ns.exercise is not None:  # checked before anything moves
        from langenv.exercise import resolve_exercise
        from langenv.exercise.check import check_exercise

        check_exercise(resolve_exercise(ns.exercise))
    policy = load_registered_policy(ns.policy)
    drag = DragUser() if ns.user == "drag" else None
    env = _make_env(ns, policy, drag)
    out = ns.audio_out

    def make_sink(ring: Any, sr: int) -> Any:
        if out is not None:
            return WavSink(ring, out, sr)
        return SoundCardSink(ring, sr, device=ns.device)

    try:
        if not ns.headless:
            from langenv.live.viewer import ViewerHooks

            viewer = ViewerHooks(env, drag)
            hooks = viewer
            viewer.countdown()
        loop = RealTimeLoop(
            env, policy, make_sink, seed=ns.seed, hooks=hooks, record=ns.trace_out is not None
        )
        report = loop.run(ns.seconds)
    finally:
        close = getattr(hooks, "close", None)
        if close is not None:
            close()
        env.close()
    line = f"play: {ns.policy}, user {ns.user}: {report.summary()}"
    written = [str(p) for p in (out, ns.trace_out) if p is not None]
    if ns.trace_out is not None:
        _write_trace(ns.trace_out, loop.rows)
    return line + (f"; wrote {', '.join(written)}" if written else "")


def _write_trace(path: Path, rows: list[tuple[Any, ...]]) -> None:
    import csv

    from langenv.live.loop import TRACE_COLUMNS

    with path.open("w", newline="") as fh:
        writer = csv.writer(fh)
        writer.writerow(TRACE_COLUMNS)
        writer.writerows(rows)


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point; returns the exit code (2 for a clear error, no traceback)."""
    ns = parse_args(argv)
    return options.run_job("play", lambda: run(ns), (LangEnvError,), interruptible=True)


if __name__ == "__main__":
    raise SystemExit(main())
