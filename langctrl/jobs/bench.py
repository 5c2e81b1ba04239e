"""``langctrl bench [--json] [--only LIST]``: speed and accuracy figures of LangCtrl, measured in
one run (each figure: :mod:`bench.figures`); ``bench-audio``, ``bench-exercises`` and
``bench-safety`` measure one part at length. Exit status 0, 2 on an unknown section.
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Sequence

from bench.figures import SECTIONS
from langctrl import options

__all__ = ["build_parser", "main"]


def build_parser() -> argparse.ArgumentParser:
    """The command line of ``langctrl bench`` (``python -m langctrl.jobs.bench``)."""
    parser = options.job_parser(
        "bench",
        "Speed and accuracy figures of LangCtrl, measured in one run (each figure: "
        "bench/figures.py's docstring).",
    )
    parser.add_argument(
        "--json", action="store_true", help="print one JSON object instead of a table"
    )
    parser.add_argument(
        "--only",
        default=",".join(SECTIONS),
        metavar="LIST",
        help=f"comma-separated sections of {', '.join(SECTIONS)} (default: all)",
    )
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Run ``langctrl bench``; returns the exit status."""
    parser = build_parser()
    args = parser.parse_args(argv)
    wanted = [s.strip() for s in args.only.split(",") if s.strip()]
    unknown = [s for s in wanted if s not in SECTIONS]
    if unknown:
        parser.error(f"unknown section(s) {unknown}; known: {list(SECTIONS)}")
    results: dict[str, float] = {}
    for name in wanted:
        if not args.json:
            print(f"measuring {name} ...", file=sys.stderr)
        results.update(SECTIONS[name]())
    rounded = {k: float(f"{v:.4g}") for k, v in results.items()}
    if args.json:
        print(json.dumps(rounded))
    else:
        from rich.console import Console
        from rich.table import Table

        table = Table(title="LangCtrl benchmark")
        table.add_column("figure")
        table.add_column("value", justify="right")
        for k, v in rounded.items():
            table.add_row(k, f"{v:g}")
        Console().print(table)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
