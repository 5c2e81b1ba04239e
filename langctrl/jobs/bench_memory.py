"""``langctrl bench-memory``: what a session of the batched env costs in memory
(:mod:`bench.memory`). Exit status 0, 2 on bad usage."""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Sequence

from bench.memory import heap_growth, machine, measure_memory, one_batch
from langctrl import options

__all__ = ["build_parser", "main"]


def build_parser() -> argparse.ArgumentParser:
    """The command line of ``langctrl bench-memory`` (``python -m langctrl.jobs.bench_memory``)."""
    p = options.job_parser(
        "bench-memory",
        "Peak memory of a batch of N sessions, each size in a fresh process, and what a session "
        "adds.",
    )
    p.add_argument(
        "--sessions", default="8,128", help="sizes, comma-separated (default: %(default)s)"
    )
    p.add_argument(
        "--one",
        type=int,
        metavar="N",
        help="N sessions in this process, its figures as JSON (what --sessions runs in fresh "
        "processes; default: off)",
    )
    p.add_argument(
        "--heap", type=int, metavar="N", help="heap growth by line for N sessions (default: off)"
    )
    return p


def main(argv: Sequence[str] | None = None) -> int:
    """Run ``langctrl bench-memory``; returns the exit status."""
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.one is not None:
        print(json.dumps(one_batch(args.one)))
        return 0
    if args.heap is not None:
        heap_growth(args.heap)
        return 0
    try:
        sizes = tuple(int(s) for s in args.sessions.split(",") if s.strip())
        figures = measure_memory(sizes)
    except ValueError as exc:
        parser.error(f"argument --sessions: {exc}")
    print(json.dumps({k: round(v, 2) for k, v in figures.items()}))
    print(f"machine: {machine()}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
