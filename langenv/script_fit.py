"""A script checked against its exercise: do its words cover the people who will do it?

A phrase graph's coverage (:mod:`langenv.speech.coverage`) is the range of motion durations its
words can end together with at a natural voice (``|a - 1| <= 0.1``). It means something only
against the exercise's motion times over the people who will do it. :func:`motion_times` gives
them: the guided motion at cooperation 1 (nobody resists) and the motion of the synthetic
population (``users`` seeded people, seeds ``0 .. users-1``, at physical pace 1, as AC moves), its
5-95 % range. They are cached on disk beside the ETC tables (``$LANGCTRL_ETC_CACHE``), keyed by
the exercise, the users' model, the robot's MuJoCo model, the package version and the source
of ``langenv``, so a check costs the simulation once per machine.

The same is measured per leg of the exercise (``MotionTimes.legs``: the time the hand spends in
each leg, from the guide's switch into it to the switch out of it).

:func:`fit_warnings` compares the two and says what would close each gap, one line each, every
line beginning ``warning:``; :func:`leg_warnings` does the same per leg for a script with
``@leg`` marks (a leg's words against the hand's time in it: :func:`leg_fit_warnings`), and
warns about a leg without words and a script without marks (aligned at the end only).
``langctrl exercise check`` prints them for an exercise's script, ``langctrl speech author
SCRIPT --exercise E`` for a script being written.
Nothing here refuses a script: a short script still ends with the motion when its last phrase
waits (the silence before it is what the warning is about).
"""

from __future__ import annotations

import hashlib
import json
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from langenv.control.etc_cache import etc_cache_dir
from langenv.control.pacing import PaceLimits
from langenv.exercise import Exercise
from langenv.files import temp_file
from langenv.speech.coverage import NATURAL, coverage, leg_lengths, natural_lengths
from langenv.speech.graph import PhraseGraph, graph_path

__all__ = [
    "POPULATION",
    "MotionTimes",
    "fit_report",
    "fit_warnings",
    "leg_fit_warnings",
    "leg_warnings",
    "motion_times",
]

POPULATION = 48
"""Synthetic people a script is checked against (seeds 0-47)."""
_FORMAT = 2  # 2: per-leg times
_LIMIT_S = 120.0  # a session the population check gives up on (s)


@dataclass(frozen=True)
class MotionTimes:
    """An exercise's motion times.

    Attributes:
        nominal: The guided motion at cooperation 1 (s).
        population: Motion time of each synthetic person at pace 1 (s), sorted.
        legs: The same for each leg of the exercise, in order: the time spent in it (empty
            when not measured).
    """

    nominal: float
    population: tuple[float, ...]
    legs: tuple[MotionTimes, ...] = ()

    @property
    def q05(self) -> float:
        """5th percentile of the population's motion times (s)."""
        return float(np.percentile(self.population, 5))

    @property
    def q95(self) -> float:
        """95th percentile of the population's motion times (s)."""
        return float(np.percentile(self.population, 95))


def motion_times(exercise: Exercise, users: int = POPULATION) -> MotionTimes:
    """The exercise's motion times (module docstring), from the cache or simulated.

    Args:
        exercise: The exercise.
        users: Synthetic people (seeds ``0 .. users-1``).
    """
    key = _key(exercise, users)
    cached = _read(key)
    if cached is not None:
        return cached
    from langenv.exercise.path_checks import guided_run

    run = guided_run(exercise)
    nominal = float(run.time) if run.time is not None else float("nan")
    people = _population(exercise, users)
    n = len(exercise.legs)
    legs = tuple(
        MotionTimes(
            run.leg_times[k] if run.leg_times else float("nan"),
            tuple(sorted(legs[k] for _, legs in people)),
        )
        for k in range(n)
    )
    out = MotionTimes(nominal, tuple(sorted(t for t, _ in people)), legs)
    _write(key, out)
    return out


def _population(exercise: Exercise, users: int) -> list[tuple[float, tuple[float, ...]]]:
    """Each seeded synthetic person's motion time at pace 1 (AC's commands) and the time they
    spend in each leg."""
    from langenv.env import LangCtrlEnv
    from langenv.exercise.path_checks import leg_times

    single = exercise.single  # the words do not move the arm at pace 1: any graph times it
    if not graph_path(single).is_file():
        single = "lc-noap"  # a script not written yet (speech author --exercise)
    env = LangCtrlEnv(
        exercise=exercise, phrase_graph=single, users="synthetic", max_seconds=_LIMIT_S
    )
    action = np.zeros(env.action_space.shape or (), np.float32)
    out = []
    try:
        for seed in range(users):
            _, info = env.reset(seed=seed)
            t, leg = [env.time], [int(info["leg"])]
            while env.time < _LIMIT_S:
                _, _, done, _, info = env.step(action)
                t.append(env.time)
                leg.append(int(info["leg"]))
                if info["t_motion"] is not None or done:
                    break
            end = info.get("t_motion")
            total = float(end) if isinstance(end, float | int) else _LIMIT_S
            out.append((total, leg_times(np.array(t), np.array(leg), len(exercise.legs), total)))
    finally:
        env.close()
    return out


def fit_warnings(
    graph: PhraseGraph, times: MotionTimes, limits: PaceLimits | None = None
) -> list[str]:
    """Where the graph's words fall short of the exercise's motion times, one ``warning:`` line
    each, naming the gap and what would close it (empty when the words cover them)."""
    cov = coverage(graph, limits)
    lo, hi = cov.natural_range
    out: list[str] = []
    name = _name(graph)
    slow, fast, nominal = times.q95, times.q05, times.nominal
    if np.isfinite(nominal) and nominal > hi:
        out.append(
            f"warning: {name}: its words cover motions up to {hi:.1f} s at a natural pace, the "
            f"motion takes {nominal:.1f} s even when nobody resists (cooperation 1); "
            + (
                "the last phrase would wait in silence. "
                if graph.final_wait
                else "the speech would run out before the motion ends. "
            )
            + "Add steps or longer wordings"
        )
    if slow > hi:
        gap = slow - hi
        if graph.final_wait:
            effect = (
                f"the last {gap:.1f} s before its last phrase would be silence for them (the "
                "last phrase waits for the motion)"
            )
        else:
            effect = f"the speech would run out {gap:.1f} s before their motion ends"
        out.append(
            f"warning: {name}: its words cover motions up to {hi:.1f} s at a natural pace, the "
            f"slowest 5 % of {len(times.population)} synthetic people take {slow:.1f} s or more; "
            f"{effect}. Add a line that may repeat, e.g. 'Keep going. | Nice and slow. "
            f"(repeat {_repeats_for(gap)}, gap 1-3)', or longer wordings"
        )
    short = min(fast, nominal) if np.isfinite(nominal) else fast
    if short < lo:
        who = "at cooperation 1" if np.isfinite(nominal) and nominal <= fast else "the fastest 5 %"
        out.append(
            f"warning: {name}: its shortest speech needs {lo:.1f} s at a natural pace, the motion "
            f"takes {short:.1f} s {who}; the voice would be sped up beyond {1 + NATURAL:g}x or "
            "end late. Make a step optional ([...]) or add shorter wordings (|)"
        )
    return out


def leg_warnings(graph: PhraseGraph, exercise: Exercise, times: MotionTimes) -> list[str]:
    """The graph's legs against the exercise's, one ``warning:`` line each: a graph without
    marks (aligned at the end only), a leg of the exercise with no words, and a leg whose words
    cannot fill or fit the time the motion spends in it (:func:`leg_fit_warnings`)."""
    name = _name(graph)
    if not graph.legs:
        return [
            f"warning: {name}: no @leg marks: its words are aligned with the motion at its end "
            f"only, not with each leg; mark each leg's lines ('@leg NAME' above them; the legs "
            f"of {exercise.name}: {', '.join(exercise.leg_names)}) to keep them in step"
        ]
    worded = {graph.leg(u) for u in graph.phrases if graph.kind(u) == "phrase"}
    out: list[str] = []
    for k, leg in enumerate(exercise.leg_names):
        if leg not in worded:
            out.append(
                f"warning: {name}: leg {leg!r} of {exercise.name} has no words (no phrase "
                f"follows '@leg {leg}'): nothing is said about it while the hand does it"
            )
        elif len(times.legs) == len(exercise.legs):
            last = k == len(exercise.legs) - 1
            out += leg_fit_warnings(name, leg, leg_lengths(graph, leg), times.legs[k], last)
    return out


def leg_fit_warnings(
    name: str, leg: str, speech: tuple[tuple[float, float], ...], times: MotionTimes, last: bool
) -> list[str]:
    """Where a leg's words (their lengths at a = 1, :func:`~langenv.speech.coverage.leg_lengths`)
    cannot fit or fill the time the motion spends in the leg (``times``), at a natural voice."""
    natural = natural_lengths(speech)
    shortest, longest = natural[0][0], natural[-1][1]
    n = len(times.population)
    nominal = times.nominal if np.isfinite(times.nominal) else times.q05
    out: list[str] = []
    fast = min(nominal, times.q05)
    if shortest > fast:
        who = (
            "at cooperation 1"
            if nominal <= times.q05
            else f"for the fastest 5 % of {n} synthetic people"
        )
        after = "past the motion's end" if last else "into the next leg"
        out.append(
            f"warning: {name}: leg {leg!r}: its words need at least {shortest:.1f} s at a natural "
            f"pace, the hand is in the leg {fast:.1f} s {who}; they would run on {after}. Make "
            "a line optional ([...]) or add shorter wordings (|)"
        )
    slow = max(nominal, times.q95)
    if longest < slow:
        who = "at cooperation 1" if nominal >= times.q95 else f"the slowest 5 % of {n} people"
        out.append(
            f"warning: {name}: leg {leg!r}: its words last at most {longest:.1f} s at a natural "
            f"pace, the hand is in the leg {slow:.1f} s ({who}); the last {slow - longest:.1f} s "
            "of it would be silence. Add longer wordings or a line that may repeat "
            f"(repeat {_repeats_for(slow - longest)}, gap 1-3) to the leg"
        )
    return out


def _name(graph: PhraseGraph) -> str:
    return graph.path.name if graph.path is not None else "the script"


def fit_report(graph: PhraseGraph, exercise: Exercise) -> list[str]:
    """The exercise's motion times, the words' natural range, :func:`fit_warnings` and
    :func:`leg_warnings`, a line each (the CLIs print them)."""
    times = motion_times(exercise)
    lo, hi = coverage(graph).natural_range
    pop = times.population
    return [
        f"  motion: {times.nominal:.1f} s at cooperation 1; {len(pop)} synthetic people at pace 1 "
        f"{pop[0]:.1f}-{pop[-1]:.1f} s (5-95 %: {times.q05:.1f}-{times.q95:.1f} s)",
        *_leg_lines(graph, exercise, times),
        f"  words of {_name(graph)}: {lo:.1f}-{hi:.1f} s at a "
        "natural pace" + ("; the last phrase waits for longer motions" if graph.final_wait else ""),
        *fit_warnings(graph, times),
        *leg_warnings(graph, exercise, times),
    ]


def _leg_lines(graph: PhraseGraph, exercise: Exercise, times: MotionTimes) -> list[str]:
    """Per leg: the hand's time in it and its words' natural range."""
    if len(times.legs) != len(exercise.legs):
        return []
    out = []
    for leg, t in zip(exercise.leg_names, times.legs, strict=True):
        words = ""
        if leg in graph.legs:
            nat = natural_lengths(leg_lengths(graph, leg))
            words = f"; its words {nat[0][0]:.1f}-{nat[-1][1]:.1f} s at a natural pace"
        out.append(
            f"  leg {leg}: {t.nominal:.1f} s at cooperation 1, {t.q05:.1f}-{t.q95:.1f} s for 5-95 %"
            + words
        )
    return out


def _repeats_for(gap: float) -> int:
    """Sayings of a ~3 s encouragement line that would fill ``gap`` seconds (2-20)."""
    return int(min(20, max(2, np.ceil(gap / 3.0) + 1)))


# ------------------------------------------------------------------------------------ cache
def _key(exercise: Exercise, users: int) -> str:
    import langenv

    root = Path(langenv.__file__).resolve().parent
    h = hashlib.sha256(f"{_FORMAT}|{langenv.__version__}|{users}|{exercise!r}".encode())
    data = [*(root / "assets" / "users").glob("*.yaml"), *(root / "robot").glob("*.xml")]
    for f in sorted([*root.rglob("*.py"), *data]):  # the code, the people, the robot's model
        h.update(f.relative_to(root).as_posix().encode())
        h.update(f.read_bytes())
    return h.hexdigest()[:32]


def _read(key: str) -> MotionTimes | None:
    root = etc_cache_dir()
    if root is None:
        return None
    try:
        data = json.loads((root / f"motion_times_{key}.json").read_text())
        return _times(data)
    except (OSError, ValueError, KeyError, TypeError):
        return None


def _times(data: dict[str, Any]) -> MotionTimes:
    """A :class:`MotionTimes` from its JSON form (:func:`_json`)."""
    legs = tuple(_times(leg) for leg in data.get("legs", []))
    return MotionTimes(float(data["nominal"]), tuple(float(x) for x in data["population"]), legs)


def _json(times: MotionTimes) -> dict[str, Any]:
    out: dict[str, Any] = {"nominal": times.nominal, "population": list(times.population)}
    if times.legs:
        out["legs"] = [_json(leg) for leg in times.legs]
    return out


def _write(key: str, times: MotionTimes) -> None:
    root = etc_cache_dir()
    if root is None:
        return
    try:
        root.mkdir(parents=True, exist_ok=True)
        fd, tmp = temp_file(root, suffix=".json.part")
        with os.fdopen(fd, "w") as f:
            json.dump(_json(times), f)
        os.replace(tmp, root / f"motion_times_{key}.json")
    except OSError:
        pass  # the cache only saves time; the ETC tables' cache warns about the directory
