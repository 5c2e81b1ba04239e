"""``langctrl listening``: does the person's pace follow the speech? The listening person's
``follow``, fitted to the study's AC sessions (how: :mod:`eval.listening`).

    langctrl listening --sessions ../shared/sessions --out out/listening

Exit status 0 when it ran, 2 on bad usage or bad session files.
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Sequence
from pathlib import Path

from eval.listening import fit_listening, write_listening
from langctrl import options

__all__ = ["build_parser", "main"]


def build_parser() -> argparse.ArgumentParser:
    """The command line of ``langctrl listening`` (``python -m langctrl.jobs.listening``)."""
    return options.job_parser(
        "listening",
        "Does the person's pace follow the speech running ahead or behind? The study's AC "
        "sessions against simulated ones: the listening person's follow, fitted.",
        options.out_dir(
            "listening.json, listening.md, listening.png", default=Path("out/listening")
        ),
        options.sessions("sessions; its *_ac.csv are read"),
        options.people(48, per="run"),
        options.seed(3000, of="the first simulated person, and of the bootstrap"),
        options.workers(),
        options.bootstrap(2000, of="of the recorded people", flag="--boot"),
    )


def main(argv: Sequence[str] | None = None) -> int:
    """Run ``langctrl listening``; returns the exit status."""
    from langenv.errors import SessionDataError

    ns = build_parser().parse_args(argv)
    t0 = time.perf_counter()
    try:
        res = fit_listening(ns.sessions, ns.users, ns.seed, ns.boot, ns.workers)
    except (SessionDataError, ValueError, OSError) as exc:
        return options.fail("listening", exc)
    print(write_listening(ns.out, res))
    print(f"wrote {ns.out} in {time.perf_counter() - t0:.1f} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
