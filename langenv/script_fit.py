"""A script checked against its exercise: do its words cover the people who will do it?

A phrase graph's coverage (:mod:`langenv.speech.coverage`) is the range of motion durations its
words can end together with at a natural voice (``|a - 1| <= 0.1``). It means something only
against the exercise's motion times over the people who will do it. :func:`motion_times` gives
them: the guided motion at cooperation 1 (nobody resists) and the motion of the synthetic
population (``users`` seeded people, seeds ``0 .. users-1``, at physical pace 1, as AC moves), its
5-95 % range. They are cached on disk beside the ETC tables (``$LANGCTRL_ETC_CACHE``), keyed by
the exercise, the users' model, the robot's MuJoCo model, the package version and the source
of ``langenv``, so a check costs the simulation once per machine.

:func:`fit_warnings` compares the two and says what would close each gap, one line each, every
line beginning ``warning:``. ``python -m langenv.exercise check`` prints them for an exercise's
script, ``python -m langenv.speech author SCRIPT --exercise E`` for a script being written.
Nothing here refuses a script: a short script still ends with the motion when its last phrase
waits (the silence before it is what the warning is about).
"""

from __future__ import annotations

import hashlib
import json
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from langenv.control.etc_cache import etc_cache_dir
from langenv.exercise import Exercise
from langenv.files import temp_file
from langenv.pacing import PaceLimits
from langenv.speech.coverage import NATURAL, coverage
from langenv.speech.graph import PhraseGraph, graph_path

__all__ = ["POPULATION", "MotionTimes", "fit_report", "fit_warnings", "motion_times"]

POPULATION = 48
"""Synthetic people a script is checked against (seeds 0-47)."""
_FORMAT = 1
_LIMIT_S = 120.0  # a session the population check gives up on (s)


@dataclass(frozen=True)
class MotionTimes:
    """An exercise's motion times.

    Attributes:
        nominal: The guided motion at cooperation 1 (s).
        population: Motion time of each synthetic person at pace 1 (s), sorted.
    """

    nominal: float
    population: tuple[float, ...]

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
    out = MotionTimes(nominal, tuple(sorted(_population(exercise, users))))
    _write(key, out)
    return out


def _population(exercise: Exercise, users: int) -> list[float]:
    """Each seeded synthetic person's motion time at pace 1 (AC's commands)."""
    from langenv.env import LangCtrlEnv

    single = exercise.single  # the words do not move the arm at pace 1: any graph times it
    if not graph_path(single).is_file():
        single = "lc-noap"  # a script not written yet (speech author --exercise)
    env = LangCtrlEnv(
        exercise=exercise, phrase_graph=single, users="synthetic", max_seconds=_LIMIT_S
    )
    action = np.zeros(env.action_space.shape or (), np.float32)
    times = []
    try:
        for seed in range(users):
            env.reset(seed=seed)
            info: dict[str, object] = {}
            while env.time < _LIMIT_S:
                _, _, done, _, info = env.step(action)
                if info["t_motion"] is not None or done:
                    break
            t = info.get("t_motion")
            times.append(float(t) if isinstance(t, float | int) else _LIMIT_S)
    finally:
        env.close()
    return times


def fit_warnings(
    graph: PhraseGraph, times: MotionTimes, limits: PaceLimits | None = None
) -> list[str]:
    """Where the graph's words fall short of the exercise's motion times, one ``warning:`` line
    each, naming the gap and what would close it (empty when the words cover them)."""
    cov = coverage(graph, limits)
    lo, hi = cov.natural_range
    out: list[str] = []
    name = graph.path.name if graph.path is not None else "the script"
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


def fit_report(graph: PhraseGraph, exercise: Exercise) -> list[str]:
    """The exercise's motion times, the words' natural range and :func:`fit_warnings`, a line
    each (the CLIs print them)."""
    times = motion_times(exercise)
    lo, hi = coverage(graph).natural_range
    pop = times.population
    return [
        f"  motion: {times.nominal:.1f} s at cooperation 1; {len(pop)} synthetic people at pace 1 "
        f"{pop[0]:.1f}-{pop[-1]:.1f} s (5-95 %: {times.q05:.1f}-{times.q95:.1f} s)",
        f"  words of {graph.path.name if graph.path else 'the script'}: {lo:.1f}-{hi:.1f} s at a "
        "natural pace" + ("; the last phrase waits for longer motions" if graph.final_wait else ""),
        *fit_warnings(graph, times),
    ]


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
        return MotionTimes(float(data["nominal"]), tuple(float(x) for x in data["population"]))
    except (OSError, ValueError, KeyError, TypeError):
        return None


def _write(key: str, times: MotionTimes) -> None:
    root = etc_cache_dir()
    if root is None:
        return
    try:
        root.mkdir(parents=True, exist_ok=True)
        fd, tmp = temp_file(root, suffix=".json.part")
        with os.fdopen(fd, "w") as f:
            json.dump({"nominal": times.nominal, "population": list(times.population)}, f)
        os.replace(tmp, root / f"motion_times_{key}.json")
    except OSError:
        pass  # the cache only saves time; the ETC tables' cache warns about the directory
