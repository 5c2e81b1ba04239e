"""Every shipped exercise under AC, LC-noAP and LC: the table of ``docs/exercises.md``.

Run::

    langctrl exercises --out out/exercises        # 48 users each

runs ``langctrl compare --exercise NAME --policies ac,lc-noap,lc`` for each shipped exercise
(into ``OUT/NAME``, figures and WAVs as usual), then reads the runs back and prints, per exercise
and controller, the medians of motion time, ``|AM|``, mean ``|EM|``, the share of speech time with
``|a - 1| <= 0.1`` and with the voice heard within 0.1 of its natural rate, the protective stops,
and the hand's largest distance from the path (from the logged joint positions: the handle's
position by forward kinematics, its distance to the nearest point of the exercise's path).
Then the headline per exercise: over LC's sessions, the largest ``|AM|``, how many end within
1 s, the means of the pause share and of the share of the voice heard natural, and how many of
the legs start their words within 1 s of the leg (``legs in step``, :mod:`eval.legs`).
``--table-only`` reads existing runs without running anything. Exit status 1 when an episode ended
in a protective stop or left the path by more than the safety's ``max_deviation``, LC's median
``|AM|`` is not below AC's, or an LC session ends more than 1 s from its motion."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np

from eval.markdown import markdown_table

__all__ = [
    "HEADLINE_AM",
    "POLICIES",
    "exercise_rows",
    "headline_row",
    "headline_table",
    "path_deviation",
    "table",
    "verdict",
]

POLICIES = ("ac", "lc-noap", "lc")
HEADLINE_AM = 1.0
"""The headline: LC's speech and motion end within this many seconds in every session (s)."""
_LABEL = {"ac": "AC", "lc-noap": "LC-noAP", "lc": "LC"}
_STRIDE = 5  # every 5th logged step (10 ms at 500 Hz)


def path_deviation(qpos: np.ndarray, exercise: Any) -> float:
    """Largest distance (m) of the handle from the exercise's path over logged joint positions."""
    import mujoco

    from langenv.robot.arm import Arm

    arm = Arm()
    m, d = arm.model, arm.data
    site = arm.site_id
    segs = exercise.trajectory.segments
    worst = 0.0
    for q in qpos[::_STRIDE]:
        d.qpos[:] = q
        mujoco.mj_kinematics(m, d)
        x = d.site_xpos[site].tolist()
        near = min(math.dist(x, s.point(s.project(*x))) for s in segs)
        worst = max(worst, near)
    return worst


def exercise_rows(run_dir: Path, name: str) -> list[dict[str, Any]]:
    """Per policy the figures of one exercise's compare run in ``run_dir``."""
    from eval.episode import EpisodeLog
    from eval.report import read_sessions_csv
    from langenv.exercise import resolve_exercise

    ex = resolve_exercise(name)
    rows = read_sessions_csv(run_dir / "sessions.csv")
    out = []
    for pol in POLICIES:
        mine = [r for r in rows if r["policy"] == pol]
        if not mine:
            continue
        dev = 0.0
        for r in mine:
            log = EpisodeLog.load_npz(run_dir / "sessions" / f"{pol}_{r['user']}.npz")
            dev = max(dev, path_deviation(np.asarray(log.qpos, np.float64), ex))
        values = {k: [float(r[k]) for r in mine] for k in ("t_motion", "abs_am", "em_mean_abs")}
        share = [float(r["a_within_0_1"]) for r in mine]
        voice = [float(r.get("voice_natural", math.nan)) for r in mine]
        finite = all(math.isfinite(v) for vs in values.values() for v in vs)
        out.append(
            {
                "exercise": name,
                "policy": _LABEL[pol],
                "episodes": len(mine),
                "t_motion": float(np.median(values["t_motion"])),
                "abs_am": float(np.median(values["abs_am"])),
                "em": float(np.median(values["em_mean_abs"])),
                "a_share": float(np.median(share)),
                "voice_share": float(np.median(voice)),
                "stops": int(sum(float(r["protective_stop"]) for r in mine)),
                "truncated": int(sum(float(r["truncated"]) for r in mine)),
                "deviation": dev,
                "finite": finite,
            }
        )
    return out


def headline_row(run_dir: Path, name: str) -> dict[str, Any]:
    """LC's headline on one exercise's run: every session's |AM| (max, share within 1 s), the
    means over sessions of the pause share and the share of the voice heard natural, and its
    legs in step: of the leg boundaries of every session (:mod:`eval.legs`), those whose words
    start within 1 s of the leg."""
    from eval.episode import EpisodeLog
    from eval.legs import leg_boundaries
    from eval.report import read_sessions_csv

    mine = [r for r in read_sessions_csv(run_dir / "sessions.csv") if r["policy"] == "lc"]
    am = [float(r["abs_am"]) for r in mine]
    legs = [
        b
        for r in mine
        for b in leg_boundaries(EpisodeLog.load_npz(run_dir / "sessions" / f"lc_{r['user']}.npz"))
    ]
    return {
        "exercise": name,
        "sessions": len(mine),
        "max_am": max(am, default=math.nan),
        "within": sum(a <= HEADLINE_AM for a in am),
        "silence": float(np.mean([float(r["pause_share"]) for r in mine])),
        "voice": float(np.mean([float(r["voice_natural"]) for r in mine])),
        "legs": len(legs),
        "legs_in_step": sum(b.in_step for b in legs),
    }


def headline_table(rows: list[dict[str, Any]]) -> str:
    """The headline rows as a Markdown table (legs in step: n/a for a script without marks)."""
    header = [
        "exercise",
        "LC sessions",
        "max abs(AM) (s)",
        "within 1 s",
        "pauses (mean)",
        "voice natural (mean)",
        "legs in step",
    ]
    cells = [
        [
            str(r["exercise"]),
            str(r["sessions"]),
            f"{r['max_am']:.2f}",
            f"{r['within']}/{r['sessions']}",
            f"{100 * r['silence']:.1f} %",
            f"{100 * r['voice']:.1f} %",
            f"{r['legs_in_step']}/{r['legs']}" if r.get("legs") else "n/a",
        ]
        for r in rows
    ]
    return "\n".join(markdown_table(header, cells))


def table(rows: list[dict[str, Any]]) -> str:
    """The rows as a Markdown table."""
    header = [
        "exercise",
        "controller",
        "motion time (s)",
        "median abs(AM) (s)",
        "median mean abs(EM) (s)",
        "share abs(a - 1) <= 0.1",
        "voice natural",
        "protective stops",
        "max path deviation (mm)",
    ]
    cells = [
        [
            str(r["exercise"]),
            str(r["policy"]),
            f"{r['t_motion']:.2f}",
            f"{r['abs_am']:.2f}",
            f"{r['em']:.2f}",
            f"{100 * r['a_share']:.0f} %",
            f"{100 * r['voice_share']:.0f} %",
            str(r["stops"]),
            f"{1000 * r['deviation']:.0f}",
        ]
        for r in rows
    ]
    return "\n".join(markdown_table(header, cells))


def verdict(rows: list[dict[str, Any]]) -> list[str]:
    """What fails in ``rows`` (:func:`exercise_rows`): stops, truncations, NaN, leaving the path,
    LC's median ``|AM|`` not below AC's; one line each."""
    from langenv.robot.safety import SafetyLimits

    limit = SafetyLimits().max_deviation
    bad = []
    for r in rows:
        if r["stops"] or r["truncated"] or not r["finite"] or r["deviation"] > limit:
            bad.append(f"{r['exercise']} {r['policy']}: stops, truncation, NaN or off the path")
    by = {(r["exercise"], r["policy"]): r["abs_am"] for r in rows}
    for ex in {r["exercise"] for r in rows}:
        if by.get((ex, "LC"), math.inf) >= by.get((ex, "AC"), -math.inf):
            bad.append(f"{ex}: LC's median |AM| is not below AC's")
    return bad
