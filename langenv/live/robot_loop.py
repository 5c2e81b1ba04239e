"""RobotLoop: one session of the controller on any robot behind the robot-IO seam.

The loop is ``LangCtrl-v0`` itself with ``robot=`` (:class:`~langenv.robot.io_arm.IOArm`): each
tick sends ``speedL``, waits for the robot's next period and reads its state, so the controller,
its safety limits and monitor, the speech and the policy are the simulation's own code. Around
it this module adds what a real session needs:

* the speech streamed to a sink (the live mode's :class:`~langenv.live.stream.SpeechStream` and
  :class:`~langenv.live.ring.AudioRing`; at most one block rendered per period, so a period's
  compute stays short), faded out over :data:`FADE_S` when the session ends or stops;
* the session CSV (:func:`~langenv.users.session_csv.write_session`): the study's columns
  (``eval.compare --sessions`` replays it) every ``log_every`` periods, then the TCP, the command,
  the measured force and the phrase; written whatever ends the session;
* Python's cyclic garbage collector paused for the session (``gc.freeze`` then ``gc.disable``;
  restored after): a full collection takes milliseconds, more than a period;
* the sink watched every ``log_every`` periods: one that died (its thread or stream) ends the
  session with the ``audio_lost`` stop (the person is no longer talked through);
* ``stop()`` (``speedStop``) on every way out: the end of the motion, a named stop, Ctrl-C
  (``interrupted``), an exception.
"""

from __future__ import annotations

import gc
import math
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from langenv.control.trajectory import Trajectory
from langenv.errors import DeviceError
from langenv.exercise import Exercise, resolve_exercise
from langenv.live.ring import AudioRing
from langenv.live.sinks import AudioSink
from langenv.live.stream import BLOCK, DEFAULT_LAG, SpeechStream
from langenv.robot.io import RobotIO
from langenv.robot.io_arm import IOArm
from langenv.robot.safety import SafetyStop
from langenv.speech.vocoder import VariableRateVocoder
from langenv.users.base import User
from langenv.users.session_csv import OPTIONAL_COLUMNS, REQUIRED_COLUMNS, write_session

__all__ = ["FADE_S", "LOG_COLUMNS", "RobotLoop", "RobotSessionReport"]

FADE_S = 0.1
"""Seconds over which the speech fades out when a session ends or stops."""

LOG_COLUMNS = (
    *REQUIRED_COLUMNS,
    *OPTIONAL_COLUMNS,
    "x",
    "y",
    "z",
    "vx_cmd",
    "vy_cmd",
    "vz_cmd",
    "fx",
    "fy",
    "fz",
    "path_deviation",
    "phrase",
)
"""Columns of the session CSV: SPEC §3's (what ``load_session`` reads), then the TCP (m), the
velocity command sent (m/s), the measured force (N, before the deadband), the distance from the
path (m) and the phrase being said."""


@dataclass(frozen=True)
class RobotSessionReport:
    """How a session on a robot went.

    Attributes:
        stop: The named stop that ended it, or None (the motion and speech ended).
        periods: Control periods run.
        duration_s: Session time (s).
        am: Speech end minus motion end (s), None after a stop.
        compute_ms: Median, 99.9th percentile and largest compute time of a period (ms, wall).
        log: The session CSV written, or None.
        cpu_ms: Median and 99.9th percentile of the same in the thread's CPU time (ms).
    """

    stop: SafetyStop | None
    periods: int
    duration_s: float
    am: float | None
    compute_ms: tuple[float, float, float]
    log: Path | None
    cpu_ms: tuple[float, float] = (math.nan, math.nan)

    def summary(self) -> str:
        """One line for the terminal."""
        if self.stop is not None:
            end = self.stop.message
        elif self.am is not None:
            end = f"finished, AM {self.am:+.2f} s"
        else:
            end = "ended at its time limit, before the motion and speech ended"
        med, p999, worst = self.compute_ms
        return (
            f"{self.duration_s:.2f} s, {self.periods} periods; compute per period median "
            f"{med:.3f} ms, p99.9 {p999:.3f} ms, max {worst:.3f} ms (CPU median "
            f"{self.cpu_ms[0]:.3f} ms, p99.9 {self.cpu_ms[1]:.3f} ms); {end}"
            + (f"; log {self.log}" if self.log is not None else "")
        )


def _warm_vocoder(sr: int) -> None:
    """Compile and run the vocoder's kernels once, before anything moves (the first pull
    otherwise costs seconds inside a control period)."""
    voc = VariableRateVocoder(sr)
    voc.push(np.zeros(4 * BLOCK, np.float32))
    voc.finish()
    voc.pull(BLOCK, 1.1)


class RobotLoop:
    """Runs one session of a policy on a robot.

    Args:
        robot: The robot, at the exercise's start and at rest.
        policy: Offers ``act(observation)``, ``reset()``, ``decision_hz``, ``graph_role``
            and ``env_kwargs`` (what :func:`langenv.live.registry.load_registered_policy` gives).
        trajectory: The exercise's path in the robot's base frame (default: the exercise's
            own, in our UR5 model's base frame).
        exercise: The exercise (a name, a YAML path or an
            :class:`~langenv.exercise.Exercise`; None: the study's): its guide speed
            (admittance) and the script the policy speaks on it, by its graph role
            (:func:`langenv.exercise.script.speak`).
        graph: For a policy that chooses phrases, a phrase graph (a shipped name or a YAML
            path) instead of the exercise's; None: the exercise's.
        make_sink: Builds the audio sink from the ring and the sample rate (None: no audio).
        log_path: The session CSV to write (None: none).
        log_every: Periods between two logged rows (10: 50 Hz, as the study's recordings).
        max_seconds: Longest session (s); the loop stops the robot there.
        acceleration: ``speedL``'s acceleration (m/s^2).
        seed: The env's seed.
    """

    def __init__(
        self,
        robot: RobotIO,
        policy: Any,
        *,
        trajectory: Trajectory | None = None,
        exercise: str | Path | Exercise | None = None,
        graph: str | Path | None = None,
        make_sink: Callable[[AudioRing, int], AudioSink] | None = None,
        log_path: str | Path | None = None,
        log_every: int = 10,
        max_seconds: float = 120.0,
        acceleration: float = 1.0,
        seed: int = 0,
    ) -> None:
        from langenv.env import LangCtrlEnv
        from langenv.exercise.script import speak

        own = dict(policy.env_kwargs).get("exercise")
        ex = resolve_exercise(exercise if exercise is not None else own)
        self.spoken = speak(policy, ex, graph)  # may fit a learned model to the graph
        drop = ("users", "exercise", "max_seconds")
        kwargs = {k: v for k, v in dict(policy.env_kwargs).items() if k not in drop}
        kwargs.setdefault("admittance", ex.admittance())
        self.exercise = ex
        self.env = LangCtrlEnv(
            robot=robot,
            exercise=ex,
            trajectory=trajectory if trajectory is not None else ex.trajectory,
            phrase_graph=self.spoken.ref,
            decision_hz=int(policy.decision_hz),
            robot_acceleration=acceleration,
            max_seconds=max_seconds,  # the loop's own length, not the env's 60 s
            **kwargs,
        )
        self.robot, self.policy = robot, policy
        self.log_path = Path(log_path) if log_path is not None else None
        self.log_every = max(1, int(log_every))
        self.max_steps = math.ceil(max_seconds * self.env.decision_hz)
        self.seed = int(seed)
        self.sr = int(self.env.clips.sr)
        self.ring = AudioRing(self.sr)
        self.sink = make_sink(self.ring, self.sr) if make_sink is not None else None
        self._rows: list[list[Any]] = []
        if self.sink is not None:
            _warm_vocoder(self.sr)

    @property
    def arm(self) -> IOArm:
        """The env's arm over the robot."""
        arm = self.env.motion.arm
        assert isinstance(arm, IOArm)
        return arm

    def simulated_person(self, user: User) -> Callable[[float, np.ndarray], np.ndarray]:
        """``user`` (reset with the loop's seed) as a simulated robot's ``person``: its force
        from the time and the TCP velocity, along the guide's tangent as in the env."""
        user.reset(np.random.default_rng(self.seed))
        motion = self.env.motion

        def person(t: float, velocity: np.ndarray) -> np.ndarray:
            return user.force(t, velocity, motion.tangent())

        return person

    def run(self) -> RobotSessionReport:
        """Run the session to its end or its first stop; always ends with ``robot.stop()``."""
        env, arm = self.env, self.arm
        info: dict[str, Any] = {}
        started = False
        collecting = gc.isenabled()
        gc.collect()
        gc.freeze()
        gc.disable()
        try:
            obs, info = env.reset(seed=self.seed)
            self.policy.reset()
            stream = SpeechStream(env.graph, env.clips, lag=DEFAULT_LAG)
            self._log(info)
            for step in range(self.max_steps):
                obs, _, terminated, truncated, info = env.step(self.policy.act(obs))
                speech = env.speech
                stream.record(
                    float(info["time"]),
                    float(info["a"]),
                    speech.path,
                    speech.done,
                    speech.pause_lengths,
                )
                if terminated or truncated:
                    break
                if self.sink is not None:
                    started = self._audio(stream, float(info["time"]), started)
                if (step + 1) % self.log_every == 0:
                    self._log(info)
                    if self.sink is not None and not self.sink.alive:
                        arm.halt("audio_lost", "the sink's thread or stream died")
                        break
        except KeyboardInterrupt:
            arm.halt("interrupted")
        finally:
            try:  # each step may fail (the sound card gone) or meet a second Ctrl-C
                try:
                    self.robot.stop()
                except DeviceError:
                    pass  # the link is gone: the robot's watchdog has stopped it
                self._fade(started)
            finally:
                gc.unfreeze()
                if collecting:
                    gc.enable()
                if info:  # the log too, whatever ended the session (an error included)
                    self._log(env._info())
                log = self._write()
        stop = env.motion.safety_stop if env.motion.safety_stop is not None else arm.fault
        compute = np.asarray(arm.compute_s) * 1e3
        stats = (
            (float(np.median(compute)), float(np.quantile(compute, 0.999)), float(compute.max()))
            if compute.size
            else (math.nan, math.nan, math.nan)
        )
        cpu = np.asarray(arm.compute_cpu_s) * 1e3
        cpu_stats = (
            (float(np.median(cpu)), float(np.quantile(cpu, 0.999)))
            if cpu.size
            else (math.nan, math.nan)
        )
        am = info.get("am") if stop is None else None
        return RobotSessionReport(stop, len(arm.compute_s), env.time, am, stats, log, cpu_stats)

    def _audio(self, stream: SpeechStream, t: float, started: bool) -> bool:
        """At most one block into the ring; start the sink once it holds enough."""
        assert self.sink is not None
        if self.ring.free() >= BLOCK:
            self.ring.write(stream.render(t, BLOCK))
        if not started and len(self.ring) >= 0.05 * self.sr:
            self.sink.start()
            return True
        return started

    def _fade(self, started: bool) -> None:
        if self.sink is None:
            return
        self.ring.fade_out(round(FADE_S * self.sr))
        if started:
            time.sleep(FADE_S + 0.02)
        self.sink.stop()

    def _log(self, info: dict[str, Any]) -> None:
        """One row from the step's info (skipped when its time is not past the last row's)."""
        t = float(info["time"])
        if self._rows and (t <= self._rows[-1][0] + 1e-4):
            return
        arm = self.arm
        x, y, z = arm.state.position.tolist()
        fx, fy, fz = arm.state.force.tolist()
        v = arm.sent.tolist()
        phrase = info["phrase"] if info["phrase"] is not None and not info["in_pause"] else ""
        self._rows.append(
            [
                t,
                min(1.0, max(0.0, float(info["cooperation"]))),
                float(info["hand_speed"]),
                float(info["a"]),
                float(info["p"]),
                float(info["t_a"]),
                float(info["t_x"]),
                float(info["t_a"]) - float(info["t_x"]),
                x,
                y,
                z,
                v[0],
                v[1],
                v[2],
                fx,
                fy,
                fz,
                float(info["path_deviation"]),
                phrase,
            ]
        )

    def _write(self) -> Path | None:
        if self.log_path is None or len(self._rows) < 2:
            return None
        columns = {name: [row[j] for row in self._rows] for j, name in enumerate(LOG_COLUMNS)}
        return write_session(self.log_path, columns)
