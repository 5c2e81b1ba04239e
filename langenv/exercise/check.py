"""Every check of an exercise before any robot moves: its script, its path, the arm along it.

:func:`check_exercise` runs the path's checks (:mod:`langenv.exercise.path_checks`: continuity,
turns, bends at the nominal speed, the guided motion and its ETC at cooperation 1), the arm's
(:mod:`langenv.exercise.reach`: IK with the tool orientation, joint margins, manipulability,
contacts) and loads the script's phrase graphs, whose ``@leg`` marks must name the exercise's
legs in its order (:func:`leg_problems`: the graph file's line and column). A legal file that
is unsafe is refused with the same detail as a malformed one: an
:class:`~langenv.errors.ExerciseError` whose ``problems`` say which leg, which point and why.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from langenv.errors import ExerciseError, LangEnvError
from langenv.exercise.path_checks import GuidedRun, path_problems
from langenv.exercise.reach import ReachReport, reach_problems
from langenv.exercise.spec import Exercise, Problem

__all__ = ["CheckReport", "check_exercise", "exercise_problems", "leg_problems"]


@dataclass(frozen=True, eq=False)
class CheckReport:
    """The figures of a checked exercise.

    Attributes:
        exercise: The exercise.
        problems: What is wrong (empty when it passed).
        run: The guided motion at cooperation 1 (time, ETC, path error, speed).
        reach: The arm along the path (joint positions, margins, manipulability, clearance).
        seconds: Wall time the checks took (s).
    """

    exercise: Exercise
    problems: tuple[Problem, ...]
    run: GuidedRun
    reach: ReachReport
    seconds: float

    @property
    def ok(self) -> bool:
        """Whether the exercise passed every check."""
        return not self.problems

    def summary(self) -> str:
        """The figures, one line each."""
        ex, run, r = self.exercise, self.run, self.reach
        t = ex.trajectory
        time_s = "did not finish" if run.time is None else f"{run.time:.2f} s"
        return "\n".join(
            [
                f"{ex.name}: {ex.title}",
                f"  legs {len(ex.legs)} ({', '.join(ex.leg_names)}), segments "
                f"{len(t.segments)}, length {t.length:.3f} m, speed {ex.speed} m/s",
                f"  motion at cooperation 1: {time_s} (ETC {run.etc:.2f} s), path error "
                f"{run.max_path_error * 1000:.1f} mm, top speed {run.max_speed:.3f} m/s",
                f"  arm: {len(r.s)} points, joint margin >= {r.min_joint_margin:.2f} rad, "
                f"manipulability (min singular value) >= {r.min_sigma:.3f}, clearance >= "
                f"{r.min_clearance * 1000:.1f} mm",
                f"  script: graph {ex.graph}, single {ex.single}",
            ]
        )


def exercise_problems(exercise: Exercise, model_path: str | Path | None = None) -> CheckReport:
    """Run every check; the report holds the problems (nothing raised for them).

    Args:
        exercise: The exercise.
        model_path: The arm's MJCF; None: our UR5.
    """
    t0 = time.perf_counter()
    problems: list[Problem] = _script_problems(exercise)
    path, run = path_problems(exercise)
    arm, reach = reach_problems(exercise, model_path)
    problems += path + arm
    return CheckReport(exercise, tuple(problems), run, reach, time.perf_counter() - t0)


def check_exercise(exercise: Exercise, model_path: str | Path | None = None) -> CheckReport:
    """Run every check and refuse an exercise that fails one.

    Returns:
        The report of a passing exercise.

    Raises:
        ExerciseError: naming the file and every problem (kind, leg, point, detail).
    """
    report = exercise_problems(exercise, model_path)
    if report.problems:
        raise ExerciseError(report.problems, exercise.path)
    return report


def _script_problems(exercise: Exercise) -> list[Problem]:
    from langenv.speech.graph import PhraseGraph, graph_path

    out = []
    for key in ("graph", "single"):
        ref = getattr(exercise, key)
        try:
            graph = PhraseGraph.load(graph_path(ref))
        except LangEnvError as exc:
            out.append(Problem("bad_graph", None, None, f"script.{key}: {exc}"))
            continue
        found = leg_problems(graph.legs, exercise.leg_names, graph_path(ref))
        hint = "; give the exercise a script of its own (docs/scripts.md) or an unmarked graph "
        hint += "(script: {graph: study})"
        if exercise.script_warning(key) is not None:  # left out: the study's marked script
            hint = (
                f" (script.{key} is left out or names a shipped graph: the study's script, "
                "marked with the legs of its shoulder external rotation)" + hint
            )
        out += [
            Problem("unknown_leg", leg, None, f"script.{key}: {where}: {why}{hint}")
            for leg, where, why in found
        ]
    return out


def leg_problems(
    legs: Sequence[str], names: Sequence[str], path: Path
) -> list[tuple[str, str, str]]:
    """A phrase graph's legs (``legs``, from the file ``path``) against an exercise's leg
    names: each leg the exercise lacks, or out of its order, as ``(leg, FILE:LINE:COL, why)``
    with where the file names it."""
    out: list[tuple[str, str, str]] = []
    last = -1
    for leg in legs:
        if leg not in names:
            why = f"{leg!r} is not a leg of the exercise; its legs: {', '.join(names)}"
        elif names.index(leg) < last:
            order = ", ".join(names)
            why = f"leg {leg!r} comes after a later leg; legs follow the exercise's order ({order})"
        else:
            last = names.index(leg)
            continue
        out.append((leg, _where(path, leg), why))
    return out


def _where(path: Path, leg: str) -> str:
    """``FILE:LINE:COL`` of ``leg`` in the graph file's ``legs`` list (``FILE`` if not found)."""
    import yaml

    try:
        root = yaml.compose(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, yaml.YAMLError):
        return str(path)
    for key, value in getattr(root, "value", ()):
        if getattr(key, "value", None) == "legs" and isinstance(value, yaml.SequenceNode):
            for item in value.value:
                if item.value == leg:
                    return f"{path}:{item.start_mark.line + 1}:{item.start_mark.column + 1}"
    return str(path)
