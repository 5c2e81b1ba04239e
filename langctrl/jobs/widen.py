"""``langctrl widen``: a saved model widened to phrase graphs with more choices, acting exactly
as before (how: :mod:`train.widen`).

    langctrl widen models/ppo_aligner.zip --max-children 9 --out runs/widened/ppo_aligner9

Exit status 0 (the widened model's path printed), 2 on a bad input.
"""

from __future__ import annotations

import argparse
from collections.abc import Sequence
from pathlib import Path

from langctrl import options
from train.widen import widen

__all__ = ["build_parser", "main"]


def build_parser() -> argparse.ArgumentParser:
    """The command line of ``langctrl widen`` (``python -m langctrl.jobs.widen``)."""
    p = options.job_parser(
        "widen",
        "Widen a saved model to phrase graphs with more choices, acting exactly as before.",
        options.out_file("stem of the widened model", metavar="STEM"),
    )
    p.add_argument("model", type=Path, metavar="MODEL.zip", help="the model zip to widen")
    p.add_argument(
        "--max-children",
        type=int,
        required=True,
        metavar="N",
        help="the new number of choices: the largest out-degree of the graphs to read (required)",
    )
    return p


def main(argv: Sequence[str] | None = None) -> int:
    """Run ``langctrl widen``; returns the exit status (2: a bad input)."""
    ns = build_parser().parse_args(argv)
    errors = (FileNotFoundError, FileExistsError, ValueError, KeyError, TypeError)
    return options.run_job("widen", lambda: widen(ns.model, ns.max_children, ns.out), errors)


if __name__ == "__main__":
    raise SystemExit(main())
