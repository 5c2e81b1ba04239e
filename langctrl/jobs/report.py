"""``langctrl report SESSIONS.csv``: ``summary.md`` (and its figure's link) from a
``sessions.csv`` (what it holds: :mod:`eval.report`). Exit status 0, 2 on bad usage."""

from __future__ import annotations

import argparse
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from eval.report import read_sessions_csv, write_summary_md
from langctrl import options

__all__ = ["build_parser", "main"]


def build_parser() -> argparse.ArgumentParser:
    """The command line of ``langctrl report`` (``python -m langctrl.jobs.report``)."""
    parser = options.job_parser(
        "report",
        "Write summary.md (and summary.png) from a sessions.csv.",
        options.out_file(
            "the summary (Markdown)", default="summary.md beside SESSIONS.csv", metavar="MD"
        ),
        options.seed(of="the bootstrap"),
        options.bootstrap(10_000),
    )
    parser.add_argument(
        "sessions",
        type=Path,
        metavar="SESSIONS.csv",
        help="sessions.csv written by langctrl compare",
    )
    parser.add_argument(
        "--reference",
        default="lc",
        metavar="POLICY",
        help="the policy the others are compared with (default: %(default)s)",
    )
    parser.add_argument(
        "--policies",
        default=None,
        metavar="LIST",
        help="comma-separated policies to show, in order (default: all, in order of first "
        "appearance)",
    )
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """``langctrl report SESSIONS_CSV [--out MD] [--reference lc] [--seed 0]``."""
    args = build_parser().parse_args(argv)
    rows = read_sessions_csv(args.sessions)
    out = args.out or args.sessions.with_name("summary.md")
    fig = out.with_name("summary.png")
    write_summary_md(
        rows,
        out,
        args.reference,
        rng=np.random.default_rng(args.seed),
        policies=args.policies.split(",") if args.policies else None,
        n_boot=args.n_boot,
        figure=fig.name if fig.exists() else None,
    )
    print(out)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
