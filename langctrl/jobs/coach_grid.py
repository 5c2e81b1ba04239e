"""``langctrl coach-grid``: LC, the best analytic policy, ``lc-coach`` and any learned model
across a grid of the listening person's assumptions, paired, with the differences from the
base (what it runs and writes: :mod:`eval.coach_grid`).

    langctrl coach-grid --role validation --users 24 --out out/coach_val   # tuning
    langctrl coach-grid --model models/ppo_coach.zip --out out/coach_grid  # the test worlds

Exit status 0 when it ran; 2 on bad arguments, a bad grid or split.
"""

from __future__ import annotations

import argparse
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from eval.coach_grid import BASE, DEFAULT_GRID, DEFAULT_SPLIT, check_coach_grid, run_coach_grid
from langctrl import options

__all__ = ["build_parser", "main", "parse_args"]


def build_parser() -> argparse.ArgumentParser:
    """The command line of ``langctrl coach-grid`` (``python -m langctrl.jobs.coach_grid``)."""
    p = options.job_parser(
        "coach-grid",
        "Coaches across a listening person's assumptions: every policy at every point of the "
        "grid, paired.",
        options.people(24, per="exercise (the role's user seeds)"),
        options.workers(),
        options.seed(of="the bootstrap"),
        options.out_dir("sessions.csv, grid.csv, grid.md, grid.png, config.json, points/"),
        options.overwrite("files in a non-empty --out (its points are run again)"),
        options.role("test", "validation for tuning"),
        options.bootstrap(2000, check=options.positive_int),
    )
    p.add_argument(
        "--grid",
        type=Path,
        default=DEFAULT_GRID,
        metavar="YAML",
        help="the grid of listening assumptions (default: %(default)s)",
    )
    p.add_argument(
        "--policies",
        default="lc,lc-fill-end,lc-coach",
        metavar="LIST",
        help="comma-separated analytic policies (default: %(default)s)",
    )
    p.add_argument(
        "--model",
        type=Path,
        action="append",
        default=[],
        metavar="ZIP",
        help="a learned model (ppo:PATH); repeat it for several (default: none)",
    )
    p.add_argument(
        "--base",
        default=BASE,
        metavar="NAME",
        help="the policy the differences are taken from (default: %(default)s)",
    )
    p.add_argument(
        "--coach",
        default=None,
        metavar="KEY=VALUE,...",
        help="lc-coach's parameters (its rule's thresholds, e.g. relax_c=0.6) (default: the "
        "shipped rule)",
    )
    p.add_argument(
        "--split",
        type=Path,
        default=DEFAULT_SPLIT,
        metavar="CONFIG",
        help="a config with a 'worlds' section (default: %(default)s)",
    )
    p.add_argument(
        "--resume",
        action="store_true",
        help="keep the points already in --out (same arguments) and run the rest (default: off)",
    )
    return p


def parse_args(argv: Sequence[str] | None = None) -> argparse.Namespace:
    """The command line."""
    return build_parser().parse_args(argv)


def main(argv: Sequence[str] | None = None) -> int:
    """Run ``langctrl coach-grid``; returns the exit status."""
    return options.run_held_out("coach-grid", parse_args(argv), check_coach_grid, _run)


def _run(ns: argparse.Namespace, checked: Any) -> str:
    text, sessions, points = run_coach_grid(ns, checked)
    return f"{text}\nwrote {ns.out} ({sessions} sessions, {points} points)"


if __name__ == "__main__":
    raise SystemExit(main())
