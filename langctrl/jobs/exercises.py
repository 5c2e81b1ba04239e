"""``langctrl exercises``: every shipped exercise under AC, LC-noAP and LC, one ``langctrl
compare`` run each, and the table of their medians (:mod:`eval.exercises`).

    langctrl exercises --out out/exercises        # 48 users each

Exit status 0 when every check passed, 1 when one failed (a compare run, a stop, a run off the
path, LC's median ``|AM|`` not below AC's, an LC session ending more than 1 s from its motion),
2 on bad usage.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from typing import Any

from eval.exercises import (
    HEADLINE_AM,
    POLICIES,
    exercise_rows,
    headline_row,
    headline_table,
    table,
    verdict,
)
from langctrl import options

__all__ = ["build_parser", "main"]


def build_parser() -> argparse.ArgumentParser:
    """The command line of ``langctrl exercises`` (``python -m langctrl.jobs.exercises``)."""
    from langenv.exercise import SHIPPED_EXERCISES

    p = options.job_parser(
        "exercises",
        "Every shipped exercise under AC, LC-noAP and LC, one langctrl compare run each, and the "
        "table of their medians.",
        options.users("synthetic:48"),
        options.listening(),
        options.seed(),
        options.workers(),
        options.out_dir("one langctrl compare run per exercise in DIR/NAME"),
    )
    p.add_argument("--table-only", action="store_true", help="read existing runs in --out")
    p.add_argument(
        "--exercises",
        default=",".join(SHIPPED_EXERCISES),
        metavar="LIST",
        help="comma-separated shipped exercises (default: all)",
    )
    return p


def main(argv: Sequence[str] | None = None) -> int:
    """Run ``langctrl exercises``; returns the exit status."""
    from langctrl.jobs.compare import main as compare
    from langenv.exercise import SHIPPED_EXERCISES

    p = build_parser()
    ns = p.parse_args(argv)
    names = [n.strip() for n in ns.exercises.split(",") if n.strip()]
    unknown = sorted(set(names) - set(SHIPPED_EXERCISES))
    if unknown or not names:
        p.error(f"--exercises: unknown {unknown or 'none given'}; known: {list(SHIPPED_EXERCISES)}")
    rows: list[dict[str, Any]] = []
    heads: list[dict[str, Any]] = []
    for name in names:
        run_dir = ns.out / name
        if not ns.table_only:
            args = ["--exercise", name, "--policies", ",".join(POLICIES), "--users", ns.users]
            args += ["--seed", str(ns.seed), "--workers", str(ns.workers), "--out", str(run_dir)]
            args += ["--listening", ns.listening] if ns.listening is not None else []
            if compare([*args, "--overwrite"]) != 0:
                return 1
        rows += exercise_rows(run_dir, name)
        heads.append(headline_row(run_dir, name))
    print(table(rows))
    print()
    print("The headline per exercise: LC's speech and motion end within 1 s in every session")
    print(headline_table(heads))
    bad = verdict(rows) + [
        f"{h['exercise']} LC: {h['sessions'] - h['within']} of {h['sessions']} sessions end more "
        f"than {HEADLINE_AM:g} s apart (max {h['max_am']:.2f} s)"
        for h in heads
        if h["within"] < h["sessions"]
    ]
    for line in bad:
        print(f"FAIL {line}", file=sys.stderr)
    return 1 if bad else 0


if __name__ == "__main__":
    raise SystemExit(main())
