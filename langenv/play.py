"""``python -m langenv.play``: try the controller live, as the person it guides.

With a display, MuJoCo's viewer opens on the arm: double-click the handle, then Ctrl + right-drag
to push on it (your drag is the person's force, through the same sensor and deadband); the robot
speaks through the sound card in real time, slowing, speeding and rewording as you resist, with
the phrase and the paces shown on screen::

    python -m langenv.play                          # LC, you are the person
    python -m langenv.play --policy ppo:models/ppo_aligner.zip
    python -m langenv.play --user synthetic --audio-out talk.wav   # watch a simulated person
    python -m langenv.play --exercise hand_to_mouth  # another exercise (checked first)

Headless (tests, servers): the same real-time loop with no window and no sound card, the audio
written to a WAV at the sound card's pace; it prints one summary line (late ticks, underruns)::

    python -m langenv.play --headless --seconds 10 --audio-out out/live.wav

Policies are found by name through the ``langctrl.policies`` entry points
(:mod:`langenv.live.registry`).
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from langenv.errors import LangEnvError

__all__ = ["main", "parse_args"]


def parse_args(argv: Sequence[str] | None = None) -> argparse.Namespace:
    """Parse the command line."""
    p = argparse.ArgumentParser(
        prog="python -m langenv.play",
        description="Run LangCtrl live: you drag the handle, the robot talks you through it.",
    )
    p.add_argument("--policy", default="lc", help="lc (default), ac, lc-noap, lc-em, ppo:PATH...")
    p.add_argument(
        "--phrase-graph",
        default=None,
        help="phrase graph YAML (default: the exercise's script for the policy)",
    )
    p.add_argument(
        "--exercise",
        default=None,
        help="exercise: a shipped name (python -m langenv.exercise list) or a YAML path, checked "
        "before anything moves (default: the study's external_rotation)",
    )
    p.add_argument(
        "--user",
        default=None,
        help="drag (you, in the viewer; the default there), synthetic (headless default) or "
        "replay:CSV",
    )
    p.add_argument("--seed", type=int, default=0, help="seed of the first session")
    p.add_argument("--headless", action="store_true", help="no window, no sound card")
    p.add_argument("--seconds", type=float, default=None, help="stop after N s (headless: needed)")
    p.add_argument("--audio-out", type=Path, default=None, help="write the audio to this WAV")
    p.add_argument("--device", default=None, help="sound card (name or index; default: system's)")
    p.add_argument(
        "--trace-out",
        type=Path,
        default=None,
        help="write one CSV row per step: session, t, p, a, cooperation, em, force, phrase",
    )
    ns = p.parse_args(argv)
    if ns.headless and (ns.seconds is None or ns.audio_out is None):
        p.error("--headless needs --seconds N and --audio-out X.wav")
    if ns.seconds is not None and not ns.seconds > 0:
        p.error(f"--seconds must be > 0, got {ns.seconds}")
    for flag, path in (("--audio-out", ns.audio_out), ("--trace-out", ns.trace_out)):
        if path is not None and not path.parent.is_dir():
            p.error(f"{flag}: no directory {path.parent}")
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

    kwargs: dict[str, Any] = dict(policy.env_kwargs)
    if user is not None:
        kwargs["users"] = user
    elif ns.user == "synthetic":
        kwargs["users"] = "synthetic"
    else:
        kwargs.update(users="replay", session=ns.user.removeprefix("replay:"))
    hz = int(policy.decision_hz)
    graph = ns.phrase_graph if ns.phrase_graph is not None else policy.phrase_graph
    if ns.exercise is not None:
        from langenv.exercise import resolve_exercise

        exercise = resolve_exercise(ns.exercise)
        kwargs["exercise"] = exercise
        if ns.phrase_graph is None:
            graph = exercise.script_for(policy.phrase_graph)
    return gym.make(
        langenv.ENV_ID,
        phrase_graph=graph,
        decision_hz=hz,
        max_episode_steps=int(120 * hz),
        **kwargs,
    )


def run(ns: argparse.Namespace) -> str:
    """Build everything, run the loop, return the summary line."""
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
    try:
        line = run(ns)
    except LangEnvError as exc:
        print(f"langenv.play: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("langenv.play: stopped", file=sys.stderr)
        return 130
    print(line)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
