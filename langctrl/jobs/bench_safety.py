"""``langctrl bench-safety``: fuzz the safety layer with adversarial users and print the figures
(what it checks: :mod:`bench.safety`).

    langctrl bench-safety --episodes 88 --seconds 60

Exit status 0, 1 when a limit was broken without a protective stop saying why, 2 on bad usage.
"""

from __future__ import annotations

import argparse
import json
import time
from collections.abc import Sequence

from bench.safety import fuzz
from langctrl import options

__all__ = ["build_parser", "main"]


def build_parser() -> argparse.ArgumentParser:
    """The command line of ``langctrl bench-safety`` (``python -m langctrl.jobs.bench_safety``)."""
    p = options.job_parser(
        "bench-safety",
        "Fuzz the safety layer with adversarial users and print the figures (one JSON object).",
        options.seed(of="the first episode (episode i: SEED + i)"),
    )
    p.add_argument(
        "--episodes",
        type=options.positive_int,
        default=88,
        help="adversarial episodes, >= 1 (default: %(default)s)",
    )
    p.add_argument(
        "--seconds", type=float, default=60.0, help="episode length, s (default: %(default)s)"
    )
    return p


def main(argv: Sequence[str] | None = None) -> int:
    """Run ``langctrl bench-safety``; returns the exit status."""
    parser = build_parser()
    args = parser.parse_args(argv)
    if not args.seconds > 0:
        parser.error("--episodes must be >= 1 and --seconds > 0")
    t0 = time.perf_counter()
    result = fuzz(args.episodes, args.seconds, args.seed)
    out = result.as_dict()
    out["wall_s"] = round(time.perf_counter() - t0, 1)
    print(json.dumps(out))
    return 1 if result.violations else 0


if __name__ == "__main__":
    raise SystemExit(main())
