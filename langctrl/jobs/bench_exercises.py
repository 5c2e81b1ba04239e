"""``langctrl bench-exercises [--json]``: what an exercise costs to load, check and follow (each
figure: :mod:`bench.exercises`). Exit status 0, 2 on bad usage."""

from __future__ import annotations

import argparse
import json
from collections.abc import Sequence

from bench.exercises import measure_checks, measure_tick
from langctrl import options

__all__ = ["build_parser", "main"]


def build_parser() -> argparse.ArgumentParser:
    """The command line of ``langctrl bench-exercises`` (``python -m
    langctrl.jobs.bench_exercises``)."""
    p = options.job_parser(
        "bench-exercises",
        "What an exercise costs to load, check and follow.",
    )
    p.add_argument("--json", action="store_true", help="print JSON instead of a table")
    return p


def main(argv: Sequence[str] | None = None) -> int:
    """Print the figures (a table, or JSON with ``--json``); returns the exit status."""
    ns = build_parser().parse_args(argv)
    figures = {**measure_tick(), **measure_checks()}
    if ns.json:
        print(json.dumps(figures, indent=2))
    else:
        for key, value in figures.items():
            print(f"{key:36s} {value:10.4f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
