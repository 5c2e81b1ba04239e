"""Command line: list the shipped exercises, check one, or draw it.

    langctrl exercise list
    langctrl exercise check NAME|FILE [NAME|FILE ...]
    langctrl exercise render NAME|FILE --out F.png

``check`` loads the file, validates it and runs every check before motion
(:mod:`langenv.exercise.check`): it prints the figures of a passing exercise, and every problem
(file, leg, point, why) of a failing one. Exit status 0 when everything passed, 1 on a bad or
unsafe exercise (messages on stderr), 2 on bad usage (an unknown name included).
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from pathlib import Path

from langctrl import options
from langenv.errors import ConfigError, ExerciseError, LangEnvError
from langenv.exercise.registry import SHIPPED_EXERCISES, exercise_path, resolve_exercise
from langenv.exercise.spec import Exercise

__all__ = ["build_parser", "main"]


def build_parser() -> argparse.ArgumentParser:
    """The command line of ``langctrl exercise`` (``python -m langctrl.jobs.exercise``)."""
    p = options.job_parser(
        "exercise",
        "List, check and draw LangCtrl therapy exercises (exercise YAML files).",
        epilog="NAME is a shipped exercise (" + ", ".join(SHIPPED_EXERCISES) + ") and FILE an "
        "exercise YAML (format: langenv/exercise/spec.py, docs/exercises.md).",
    )
    sub = p.add_subparsers(dest="command", required=True, metavar="{list,check,render}")
    sub.add_parser("list", help="the shipped exercises, one a line")
    c = sub.add_parser("check", help="load, validate and check exercises before any motion")
    c.add_argument(
        "exercises", nargs="+", metavar="NAME|FILE", help="shipped exercise names or YAML files"
    )
    r = sub.add_parser(
        "render",
        parents=[options.out_file("PNG file")],
        help="draw an exercise's path over the arm (PNG)",
    )
    r.add_argument("exercise", metavar="NAME|FILE", help="a shipped exercise name or a YAML file")
    r.add_argument(
        "--width", type=int, default=960, help="image width, pixels (default: %(default)s)"
    )
    r.add_argument(
        "--height", type=int, default=720, help="image height, pixels (default: %(default)s)"
    )
    return p


def _list() -> int:
    for name, path in SHIPPED_EXERCISES.items():
        try:
            title = resolve_exercise(path).title
        except LangEnvError as exc:
            title = f"(invalid: {str(exc).splitlines()[0]})"
        print(f"{name:24s} {title}")
    return 0


def _check(specs: Sequence[str]) -> int:
    from langenv.exercise.check import check_exercise

    status = 0
    for spec in specs:
        try:
            report = check_exercise(resolve_exercise(spec))
        except ExerciseError as exc:
            status = options.fail_lines(exc)
            n = len(exc.problems)
            print(f"{spec}: REFUSED ({n} problem{'' if n == 1 else 's'})", file=sys.stderr)
            continue
        print(report.summary())
        print(f"  OK (checked in {report.seconds:.2f} s)")
        for role in ("graph", "single"):
            if (warning := report.exercise.script_warning(role)) is not None:
                print(warning)
        for line in _script_fit(report.exercise):
            print(line)
    return status


def _script_fit(exercise: Exercise) -> list[str]:
    """The script's words against the exercise's motion times (warnings included)."""
    from langenv.script_fit import fit_report
    from langenv.speech.graph import PhraseGraph, graph_path

    return fit_report(PhraseGraph.load(graph_path(exercise.graph)), exercise)


def _render(spec: str, out: Path, width: int, height: int) -> int:
    from langenv.exercise.render import render_exercise

    path = render_exercise(resolve_exercise(spec), out, width=width, height=height)
    print(f"wrote {path}")
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line; returns the exit status."""
    args = build_parser().parse_args(argv)
    try:
        names = args.exercises if args.command == "check" else [getattr(args, "exercise", "")]
        for spec in names if args.command != "list" else []:
            exercise_path(spec)  # an unknown name or a missing file is a usage error
    except ConfigError as exc:
        return options.fail("exercise", exc)
    try:
        if args.command == "list":
            return _list()
        if args.command == "check":
            return _check(args.exercises)
        return _render(args.exercise, args.out, args.width, args.height)
    except (LangEnvError, OSError) as exc:
        return options.fail_lines(exc)


if __name__ == "__main__":
    sys.exit(main())
