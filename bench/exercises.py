"""``python -m bench.exercises [--json]``: what an exercise costs to load, check and follow.

| key | meaning |
|---|---|
| ``load_check_s.NAME`` | loading (YAML, spline fit) and every check (``langenv.exercise.check``) of a shipped exercise, in a process that has imported the package and checked one exercise before (s); the motion-ETC tables come from the disk cache (a new exercise builds them once, a few s) |
| ``etc_build_s`` | building the motion-ETC tables of an exercise the cache has not seen (s) |
| ``tick_us_3`` / ``tick_us_30`` | one 500 Hz tick (compiled) along the study's exercise as 3 segments, and the same path with each leg cut into 10 segments (30), the hand guided from rest for 4 s (µs; best of alternating batches) |
| ``tick_growth`` | ``tick_us_30 / tick_us_3 - 1``: the cost of 27 more segments per tick (target below 0.10) |
"""

from __future__ import annotations

import argparse
import json
import math
import os
import tempfile
import time
from typing import Any

import numpy as np

from langenv.control.trajectory import ArcSegment, LineSegment, Segment, Trajectory


def split_path(traj: Trajectory, pieces: int) -> Trajectory:
    """The same path with every segment cut into ``pieces`` equal segments (same legs, turns)."""
    out: list[Segment] = []
    for seg in traj.segments:
        turn = float(seg.turn or 0.0) / pieces
        for k in range(pieces):
            last = k == pieces - 1
            start = out[-1].end if out else seg.start
            if isinstance(seg, ArcSegment):
                piece: Segment = ArcSegment(
                    seg.center, seg.axis, start, seg.angle / pieces, seg.waypoint and last, turn
                )
            else:
                end = seg.end if last else seg.start + (seg.end - seg.start) * (k + 1) / pieces
                piece = LineSegment(start, end, seg.waypoint and last, turn)
            out.append(piece)
    return Trajectory(out)


def _motion(traj: Trajectory) -> Any:
    from langenv.control.admittance import AdmittanceParams
    from langenv.control.cooperation import CooperationFilter
    from langenv.motion.tick import GuidedArm
    from langenv.robot.arm import Arm
    from langenv.robot.force_sensor import ForceSensor

    return GuidedArm(Arm(), traj, AdmittanceParams(), ForceSensor(), CooperationFilter())


def measure_tick(n: int = 2000, rounds: int = 7) -> dict[str, float]:
    """Tick cost along 3 and 30 segments of the same path, alternating batches, best of each."""
    from langenv.control.trajectory import default_exercise

    base = default_exercise()
    motions = {3: _motion(base), 30: _motion(split_path(base, 10))}
    zero = np.zeros(3)
    best = {k: math.inf for k in motions}
    for _ in range(rounds):
        for k, m in motions.items():
            m.reset()
            t0 = time.perf_counter()
            for _ in range(n):
                m.tick(zero, 1.0, 0.0)
            best[k] = min(best[k], (time.perf_counter() - t0) / n)
    a, b = best[3] * 1e6, best[30] * 1e6
    return {"tick_us_3": a, "tick_us_30": b, "tick_growth": b / a - 1.0}


def measure_checks() -> dict[str, float]:
    """Load + check of each shipped exercise (warm process, cached ETC tables), and one build."""
    from langenv.control.admittance import AdmittanceParams, VariableAdmittance
    from langenv.control.guide import Guide
    from langenv.control.motion_etc import FastETC
    from langenv.exercise import SHIPPED_EXERCISES, load_exercise
    from langenv.exercise.check import check_exercise

    out: dict[str, float] = {}
    check_exercise(load_exercise(SHIPPED_EXERCISES["external_rotation"]))  # imports, caches
    for name, path in SHIPPED_EXERCISES.items():
        t0 = time.perf_counter()
        check_exercise(load_exercise(path))
        out[f"load_check_s.{name}"] = time.perf_counter() - t0
    traj = split_path(load_exercise(SHIPPED_EXERCISES["hand_to_mouth"]).trajectory, 2)
    with tempfile.TemporaryDirectory() as tmp:
        old = os.environ.get("LANGCTRL_ETC_CACHE")
        os.environ["LANGCTRL_ETC_CACHE"] = tmp
        try:
            params = AdmittanceParams(switch_tol=0.0351)  # a key no cache has seen
            t0 = time.perf_counter()
            FastETC(Guide(traj, params), VariableAdmittance(params))
            out["etc_build_s"] = time.perf_counter() - t0
        finally:
            if old is None:
                os.environ.pop("LANGCTRL_ETC_CACHE")
            else:
                os.environ["LANGCTRL_ETC_CACHE"] = old
    return out


def main(argv: list[str] | None = None) -> int:
    """Print the figures (a table, or JSON with ``--json``)."""
    p = argparse.ArgumentParser(prog="python -m bench.exercises", description=__doc__)
    p.add_argument("--json", action="store_true")
    ns = p.parse_args(argv)
    figures = {**measure_tick(), **measure_checks()}
    if ns.json:
        print(json.dumps(figures, indent=2))
    else:
        for key, value in figures.items():
            print(f"{key:36s} {value:10.4f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
