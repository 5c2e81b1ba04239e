"""``python -m bench [--json]``: speed and accuracy figures of LangCtrl, measured in one run.

Figures (all measured here, on this machine, in this process):

| key | meaning |
|---|---|
| ``mj_step_us`` | bare ``mj_step`` of our UR5 model (µs) |
| ``tick_us`` | one full 500 Hz tick: user force, sensor, cooperation, guide (projection + F_virtual), admittance, velocity controller, physics, fast ``t_x`` (µs) |
| ``tick_ratio`` | ``tick_us / mj_step_us`` (same run) |
| ``etc_us`` | fast motion ETC per call (µs) |
| ``etc_rel_err`` | largest relative error of the fast ETC against the 500 Hz reference simulation, over states along the default exercise |
| ``nominal_s`` | time to complete the default exercise with ``F_ext = 0``, ``p = 1`` (s): the last leg done and the hand braked to rest |
| ``plateau_speed`` | highest hand speed in that run (m/s) |
| ``max_path_dev_m`` | largest distance of the hand from the path along the legs (closest point more than 8 cm from a leg's ends: the turn at a corner takes about that much of the next leg) in that run (m) |
| ``corner_overshoot_m`` | largest distance of the hand from the path anywhere in that run (m): at the corners the hand, braking at ``max_acceleration`` from the switch 3.5 cm before a leg's end, overshoots |
| ``env_step_us`` | one ``LangCtrl-v0`` step at 25 Hz (20 ticks: user, pacing, speech, the tick) with a fixed action, default env, over whole episodes with their reset (µs) |
| ``env_steps_per_s`` | ``1e6 / env_step_us``: env steps per second on one core |
| ``env_step_ratio`` | ``env_step_us / (20 mj_step_us)``, with ``mj_step_us`` measured again in rounds alternating with the episodes (target <= 1.5) |
| ``single_steps_per_s``, ``batched_steps_per_s``, ``batched_ratio`` | the single env and the batched env (``langenv.batch``: 32 sessions, every core) measured alternating in one run (``bench/batched.py``): steps per second (all sessions together) and the median of the rounds' ratios; with ``batched_sessions``, ``batched_threads`` and ``load_1min`` (the machine's load average: other programs share the cores) |
| ``batch_rss_8_mib``, ``batch_rss_128_mib``, ``batch_mib_per_session`` | peak resident memory (MiB) of a process that builds ``gym.make_vec("LangCtrl-v0", num_envs=N)``, resets it and takes 50 steps, for N = 8 and 128 (each in a fresh process: ``bench/memory.py``), and what a session adds, ``(RSS(128) - RSS(8)) / 120`` (target <= 1) |
| ``train_steps_per_s`` | PPO with the shipped recipe (``configs/ppo.yaml``: 32 envs stepped as one batched env, ``--vec-env auto``, the residual LC wrappers on the batch) for 16384 steps: env steps per second of ``model.learn`` (rollouts and updates; building the envs not counted) |
| ``audio_rtf`` | seconds of speech rendered by the variable-rate phase vocoder per second of wall time |
| ``robot_compute_median_ms``, ``robot_compute_p999_ms``, ``robot_compute_max_ms`` | the UR bridge's loop against the fake ur-rtde (virtual clock, no audio): compute time per 2 ms period, wall clock (read, control, speech, LC policy, log, ``speedL``) over 3 whole sessions (targets: median < 0.5 ms, p99.9 < 1.5 ms); preemption by other processes included |
| ``robot_cpu_median_ms``, ``robot_cpu_p999_ms`` | the same periods in the thread's CPU time: what the loop's code costs |
| ``live_wall_over_sim``, ``live_late_ticks`` | the live mode's headless real-time loop (LC at 25 Hz, speech to a WAV) over 3 s of simulated time: its wall time over the simulated time (target: 1, within 0.5 s) and the ticks that ran late |
| ``ur_no_answer_s`` | how long the UR bridge takes to refuse a host that does not answer (a non-routable address, ``connect_timeout`` 1 s; at most that) |
| ``compare_s`` | wall time of the main job: ``eval.compare`` with AC, LC-noAP and LC on 12 synthetic users (all outputs) |
| ``sweep_sps_1``, ``sweep_sps_2`` | sessions per second of a small sweep (``bench/sweep.py``) with 1 and 2 local worker processes |
| ``sweep_scaling`` | ``sweep_sps_2 / sweep_sps_1`` |
| ``cpu_scaling``, ``sweep_scaling_efficiency`` | a pure-Python loop's throughput in 2 processes over 1 (what a shared machine gives), and ``sweep_scaling / cpu_scaling`` |
| ``sweep_session_s`` | wall time per session with 1 worker (s) |
| ``sweep_cpu_per_session_1``, ``sweep_cpu_per_session_2``, ``sweep_task_overhead_2`` | CPU time per session in the workers (s) with 1 and 2 workers, and with 2 the workers' time outside batches over their time in batches |
| ``sweep_ray_cpu_per_session``, ``sweep_ray_overhead_cpu``, ``sweep_ray_task_overhead`` | the same on Ray, and Ray's extra CPU time per session as a share of the process backend's |
| ``sweep_ray_sps_2``, ``sweep_ray_overhead`` | the same sweep on Ray (``--address local``, 2 warmed actors): sessions per second, and Ray's extra time per session as a share of a session's time, the one-off start and end apart (where Ray is installed; target < 5 %) |
| ``sweep_ray_thread_cpu`` | Ray's own CPU per session: a Ray actor's other threads' CPU during its batches as a share of the sessions' thread, minus the same share in a process worker |
| ``sweep_ray_startup_s``, ``sweep_ray_shutdown_s``, ``sweep_ray_overhead_total`` | Ray's one-off start (a private Ray started, its actors warmed) and end (s), and this small sweep's whole time on Ray (start and end included) over the process backend's, minus 1 |
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from collections.abc import Callable
from typing import Any

import mujoco
import numpy as np


def _best_of(fn: Callable[[], None], n_inner: int, repeats: int = 5) -> float:
    """Smallest mean time per call (s) over ``repeats`` batches of ``n_inner`` calls."""
    best = float("inf")
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        best = min(best, (time.perf_counter() - t0) / n_inner)
    return best


def _make_motion() -> Any:
    from langenv.control.admittance import AdmittanceParams
    from langenv.control.cooperation import CooperationFilter
    from langenv.control.trajectory import default_exercise
    from langenv.motion.tick import GuidedArm
    from langenv.robot.arm import Arm
    from langenv.robot.force_sensor import ForceSensor

    return GuidedArm(
        Arm(), default_exercise(), AdmittanceParams(), ForceSensor(), CooperationFilter()
    )


def measure_physics(n: int = 2000) -> dict[str, float]:
    """mj_step, full tick and their ratio, measured back to back."""
    motion = _make_motion()
    model, data = motion.arm.model, motion.arm.data
    motion.reset()
    zero = np.zeros(3)

    def bare() -> None:
        for _ in range(n):
            mujoco.mj_step(model, data)

    def ticks() -> None:
        motion.reset()
        for _ in range(n):
            motion.tick(zero, 1.0, 0.0)

    mj = _best_of(bare, n)
    tick = _best_of(ticks, n)
    return {"mj_step_us": mj * 1e6, "tick_us": tick * 1e6, "tick_ratio": tick / mj}


_TURN_ZONE = 0.08  # m: the turn at a corner takes about this much of the next leg


def _path_distance(traj: Any, x: np.ndarray) -> float:
    """Distance from ``x`` to the nearest point of the path (any segment), m."""
    best = math.inf
    for seg in traj.segments:
        p = seg.point(seg.project(*x.tolist()))
        best = min(best, math.dist(p, x.tolist()))
    return best


def measure_nominal(max_time: float = 30.0) -> dict[str, float]:
    """Default exercise with F_ext = 0 and p = 1 on the full arm."""
    motion = _make_motion()
    motion.reset()
    traj = motion.trajectory
    ends = np.concatenate([[0.0], traj.waypoint_s])
    zero = np.zeros(3)
    top_speed = 0.0
    leg_dev = corner_dev = 0.0
    while not motion.motion_done and motion.time < max_time:
        motion.tick(zero, 1.0, 0.0)
        x = motion.hand_position
        top_speed = max(top_speed, float(np.linalg.norm(motion.hand_velocity)))
        dist = _path_distance(traj, x)
        corner_dev = max(corner_dev, dist)
        if float(np.min(np.abs(ends - motion.state.s))) > _TURN_ZONE:
            leg_dev = max(leg_dev, dist)
    nominal = motion.t_motion_end if motion.t_motion_end is not None else float("nan")
    return {
        "nominal_s": nominal,
        "plateau_speed": top_speed,
        "max_path_dev_m": leg_dev,
        "corner_overshoot_m": corner_dev,
    }


def measure_etc() -> dict[str, float]:
    """Fast motion ETC against the 500 Hz reference."""
    from bench.etc_agreement import etc_agreement
    from langenv.control.admittance import AdmittanceParams
    from langenv.control.trajectory import default_exercise

    res = etc_agreement(default_exercise(), AdmittanceParams(), np.random.default_rng(0))
    return {"etc_us": float(res["etc_us"]), "etc_rel_err": float(res["max_rel_err"])}


def measure_env(rounds: int = 9, n_bare: int = 4000) -> dict[str, float]:
    """``LangCtrl-v0`` at 25 Hz with a fixed action, and a bare ``mj_step`` of its model.

    One round is one whole episode (its reset included: a step's cost as an agent pays it) and
    then ``n_bare`` bare steps; the rounds alternate, so both figures see the same load from
    other programs, and each is the best of ``rounds``.
    """
    from langenv.env import LangCtrlEnv
    from langenv.robot.arm import Arm

    env = LangCtrlEnv(decision_hz=25)
    action = np.zeros(env.action_space.shape or (0,))
    arm = env.motion.arm
    assert isinstance(arm, Arm)
    model, data = arm.model, arm.data

    def episode() -> float:
        """Seconds per step of one episode (seed 0), reset included."""
        t0 = time.perf_counter()
        env.reset(seed=0)
        steps = 1
        while not env.step(action)[2] and steps < 1500:  # 1500: the registered time limit
            steps += 1
        return (time.perf_counter() - t0) / steps

    def bare() -> float:
        t0 = time.perf_counter()
        for _ in range(n_bare):
            mujoco.mj_step(model, data)
        return (time.perf_counter() - t0) / n_bare

    episode()  # warm up (compiled code loaded, tables built)
    step = mj = float("inf")
    for _ in range(rounds):
        step = min(step, episode())
        mj = min(mj, bare())
    env.close()
    return {
        "env_step_us": step * 1e6,
        "env_steps_per_s": 1.0 / step,
        "env_step_ratio": step / (env.ticks_per_step * mj),
    }


def measure_batched() -> dict[str, float]:
    """The batched env's steps per second against the single env's, alternating."""
    from bench.batched import measure_batched as batched

    return batched()


def measure_memory() -> dict[str, float]:
    """Peak memory of a batch of 8 and of 128 sessions, and a session's share."""
    from bench.memory import measure_memory as memory

    return memory((8, 128))


def measure_train(total: int = 16384) -> dict[str, float]:
    """PPO with the shipped config for ``total`` steps: env steps per second of learning."""
    import contextlib
    import io
    import tempfile
    from pathlib import Path

    import yaml

    from train.ppo import main as train

    with tempfile.TemporaryDirectory() as tmp:
        config = Path(__file__).resolve().parents[1] / "configs" / "ppo.yaml"
        argv = ["--config", str(config), "--out", f"{tmp}/run", "--name", "bench"]
        argv += ["--total-timesteps", str(total), "--eval-freq", "1000000000"]
        argv += ["--checkpoint-freq", "1000000000", "--no-progress-bar", "--no-tensorboard"]
        with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
            rc = train(argv)
        if rc != 0:
            raise RuntimeError(f"train.ppo exited with {rc}")
        cfg = yaml.safe_load(Path(f"{tmp}/run/bench_config.yaml").read_text())
    return {"train_steps_per_s": float(cfg["num_timesteps"]) / float(cfg["wall_time_s"])}


def measure_audio() -> dict[str, float]:
    """Variable-rate phase vocoder throughput."""
    from bench.audio import measure_audio_rtf

    return {"audio_rtf": float(measure_audio_rtf())}


def measure_sweep() -> dict[str, float]:
    """Sweep throughput with 1 and 2 workers, and Ray's overhead (``bench/sweep.py``)."""
    from bench.sweep import measure_sweep as sweep

    return sweep()


def measure_compare() -> dict[str, float]:
    """The three-controller comparison on 12 synthetic users, every output written."""
    import contextlib
    import io
    import tempfile

    from eval.compare import main as compare

    with tempfile.TemporaryDirectory() as tmp:
        t0 = time.perf_counter()
        with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
            rc = compare(
                [
                    "--policies",
                    "ac,lc-noap,lc",
                    "--users",
                    "synthetic:12",
                    "--seed",
                    "0",
                    "--out",
                    f"{tmp}/out",
                ]
            )
        elapsed = time.perf_counter() - t0
    if rc != 0:
        raise RuntimeError(f"eval.compare exited with {rc}")
    return {"compare_s": elapsed}


def measure_robot(sessions: int = 3) -> dict[str, float]:
    """The UR bridge's loop compute time per period, against the fake ur-rtde."""
    from langenv.live.registry import load_registered_policy
    from langenv.live.robot_loop import RobotLoop
    from langenv.live.ur_exercise import exercise_trajectory
    from langenv.live.ur_preflight import move_to_start
    from langenv.robot.ur import fake_rtde
    from langenv.robot.ur.bridge import URRobot
    from langenv.robot.ur.config import URConfig

    cfg = URConfig(host="127.0.0.1")  # the fake's loopback host: nothing goes on the network
    times: list[float] = []
    cpu: list[float] = []
    for _ in range(sessions):
        with fake_rtde.FakeUR(cfg.host):
            robot = URRobot(cfg, backend=fake_rtde)
            move_to_start(robot, cfg, lambda q: True)
            loop = RobotLoop(
                robot, load_registered_policy("lc"), trajectory=exercise_trajectory(cfg)
            )
            loop.run()
            times.extend(loop.arm.compute_s)
            cpu.extend(loop.arm.compute_cpu_s)
            robot.close()
    ms, cpu_ms = np.array(times) * 1e3, np.array(cpu) * 1e3
    return {
        "robot_compute_median_ms": float(np.median(ms)),
        "robot_compute_p999_ms": float(np.quantile(ms, 0.999)),
        "robot_compute_max_ms": float(ms.max()),
        "robot_cpu_median_ms": float(np.median(cpu_ms)),
        "robot_cpu_p999_ms": float(np.quantile(cpu_ms, 0.999)),
    }


def measure_live(seconds: float = 3.0) -> dict[str, float]:
    """The headless real-time loop's pace, and the time to refuse a silent robot."""
    import tempfile
    from pathlib import Path

    import gymnasium as gym

    import langenv
    from langenv.live.loop import RealTimeLoop
    from langenv.live.sinks import WavSink
    from policies.analytic import make_analytic

    env = gym.make(langenv.ENV_ID, phrase_graph="lc", decision_hz=25)
    with tempfile.TemporaryDirectory() as tmp:
        wav = Path(tmp) / "live.wav"
        loop = RealTimeLoop(
            env, make_analytic("lc", decision_hz=25), lambda r, sr: WavSink(r, wav, sr), prefill=0.5
        )
        report = loop.run(seconds)
    env.close()
    return {
        "live_wall_over_sim": report.wall_s / report.sim_s,
        "live_late_ticks": float(report.late_ticks),
        "ur_no_answer_s": _no_answer_s(),
    }


def _no_answer_s(host: str = "10.255.255.1", timeout: float = 1.0) -> float:
    """Wall time of the bridge's reachability probe against an address nobody answers."""
    from langenv.robot.ur.bridge import _probe

    t0 = time.perf_counter()
    try:
        _probe(host, timeout)
    except OSError:
        pass
    return time.perf_counter() - t0


SECTIONS: dict[str, Callable[[], dict[str, float]]] = {
    "physics": measure_physics,
    "nominal": measure_nominal,
    "etc": measure_etc,
    "env": measure_env,
    "batched": measure_batched,
    "memory": measure_memory,
    "train": measure_train,
    "audio": measure_audio,
    "compare": measure_compare,
    "robot": measure_robot,
    "live": measure_live,
    "sweep": measure_sweep,
}


def build_parser() -> argparse.ArgumentParser:
    """The command line of ``langctrl bench`` (``python -m bench``)."""
    parser = argparse.ArgumentParser(
        prog="langctrl bench",
        description="Speed and accuracy figures of LangCtrl, measured in one run (each figure: "
        "bench/__main__.py's docstring). Also run as python -m bench.",
    )
    parser.add_argument(
        "--json", action="store_true", help="print one JSON object instead of a table"
    )
    parser.add_argument(
        "--only",
        default=",".join(SECTIONS),
        metavar="LIST",
        help=f"comma-separated sections of {', '.join(SECTIONS)} (default: all)",
    )
    return parser


def main(argv: list[str] | None = None) -> int:
    """Entry point; returns the exit status."""
    parser = build_parser()
    args = parser.parse_args(argv)
    wanted = [s.strip() for s in args.only.split(",") if s.strip()]
    unknown = [s for s in wanted if s not in SECTIONS]
    if unknown:
        parser.error(f"unknown section(s) {unknown}; known: {list(SECTIONS)}")
    results: dict[str, float] = {}
    for name in wanted:
        if not args.json:
            print(f"measuring {name} ...", file=sys.stderr)
        results.update(SECTIONS[name]())
    rounded = {k: float(f"{v:.4g}") for k, v in results.items()}
    if args.json:
        print(json.dumps(rounded))
    else:
        from rich.console import Console
        from rich.table import Table

        table = Table(title="LangCtrl benchmark")
        table.add_column("figure")
        table.add_column("value", justify="right")
        for k, v in rounded.items():
            table.add_row(k, f"{v:g}")
        Console().print(table)
    return 0


if __name__ == "__main__":
    sys.exit(main())
