"""``langctrl fidelity``: replay the recorded sessions and measure the simulation against them
(what it measures and writes: :mod:`eval.fidelity`).

    langctrl fidelity --sessions ../shared/sessions --out out/fidelity
    langctrl fidelity --sessions ../shared/sessions --users synthetic:48 --seed 0

Exit status 0 when it ran, whatever the verdicts; 2 on bad usage or bad session files.
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Sequence
from pathlib import Path

from eval.fidelity import run_fidelity
from langctrl import options

__all__ = ["build_parser", "main"]


def build_parser() -> argparse.ArgumentParser:
    """The command line of ``langctrl fidelity`` (``python -m langctrl.jobs.fidelity``)."""
    p = options.job_parser(
        "fidelity",
        "Replay recorded sessions and measure the simulation against them.",
        options.out_dir("fidelity.md, fidelity.png, fidelity.json", default=Path("out/fidelity")),
        options.users(
            None,
            unless="none; with it, N simulated users also run under each "
            "controller, their motion times and cooperation compared with the "
            "recordings'",
        ),
        options.listening(),
        options.sessions("session CSVs: *_ac.csv, *_lcnoap.csv, *_lc.csv"),
        options.seed(),
        options.workers(),
    )
    return p


def main(argv: Sequence[str] | None = None) -> int:
    """Run ``langctrl fidelity``; returns the exit status."""
    from eval.users import parse_users
    from langenv.errors import SessionDataError

    args = build_parser().parse_args(argv)
    t0 = time.perf_counter()
    try:
        spec = None
        if args.users is not None or args.listening is not None:
            if args.users is None:
                raise ValueError("--listening sets listening people: give --users listening:N")
            spec = parse_users(args.users, args.listening)
        checks = run_fidelity(args.sessions, args.out, spec, args.seed, args.workers)
    except (SessionDataError, ValueError, OSError) as exc:
        return options.fail("fidelity", exc)
    width = max(len(c.name) for c in checks)
    for c in checks:
        print(
            f"{c.name:<{width}}  {c.measured:<28} {c.target:<14} {'PASS' if c.passed else 'FAIL'}"
        )
    n_pass = sum(c.passed for c in checks)
    print(f"{n_pass}/{len(checks)} PASS; wrote {args.out} in {time.perf_counter() - t0:.1f} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
