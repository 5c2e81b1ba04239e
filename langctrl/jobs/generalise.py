"""``langctrl generalise``: does a learned policy generalise? Every policy on every held-out
exercise and person (what it runs, the bars it checks, what it writes: :mod:`eval.generalise`).

    langctrl generalise --model runs/speech/best.zip --out out/generalise
    langctrl generalise --model M1.zip --model M2.zip --role test --users 48 \
        --population both --out out/test_look_1

Exit status 0 when it ran, whether or not the bars hold (``generalise.md`` says); 2 on bad
arguments or a bad split.
"""

from __future__ import annotations

import argparse
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from eval.generalise import BASE, POPULATIONS, check_generalise, run_generalise
from langctrl import options

__all__ = ["build_parser", "main", "parse_args"]


def build_parser() -> argparse.ArgumentParser:
    """The command line of ``langctrl generalise`` (``python -m langctrl.jobs.generalise``)."""
    p = options.job_parser(
        "generalise",
        "Does a learned policy generalise? Every policy on every held-out exercise and person.",
        options.people(24, per="exercise (the role's user seeds)"),
        options.workers(),
        options.seed(of="the bootstrap"),
        options.out_dir(
            "sessions.csv, generalise.md, figures, config.json; refused when it holds files"
        ),
        options.overwrite("files in a non-empty --out"),
        options.role("validation", "test only for the models you ship, at most twice"),
        options.bootstrap(2000),
    )
    p.add_argument(
        "--model",
        type=Path,
        action="append",
        required=True,
        metavar="ZIP",
        help="a learned model (.zip; required; repeat it for several)",
    )
    p.add_argument(
        "--policies",
        default="ac,lc-noap,lc,lc-em-end,lc-fill,lc-fill-end",
        metavar="LIST",
        help="comma-separated analytic policies to compare it with (default: %(default)s)",
    )
    p.add_argument(
        "--base",
        default=BASE,
        metavar="NAME",
        help="the analytic policy of --policies the bars hold the learned ones against "
        "(default: %(default)s)",
    )
    p.add_argument(
        "--split",
        default=None,
        metavar="CONFIG",
        help="a training config with a 'worlds' section (default: the split recorded with the "
        "first model)",
    )
    p.add_argument(
        "--population",
        choices=tuple(POPULATIONS),
        default=None,
        help="the split's perturbed people, the plain synthetic population, or both "
        "(default: perturbed)",
    )
    p.add_argument(
        "--no-perturb",
        action="store_true",
        help="the plain synthetic population instead of the split's perturbed users "
        "(--population plain)",
    )
    return p


def parse_args(argv: Sequence[str] | None = None) -> argparse.Namespace:
    """The command line (``--no-perturb`` is ``--population plain``)."""
    p = build_parser()
    ns = p.parse_args(argv)
    if ns.no_perturb and ns.population not in (None, "plain"):
        p.error("--no-perturb is --population plain")
    ns.population = ns.population or ("plain" if ns.no_perturb else "perturbed")
    return ns


def main(argv: Sequence[str] | None = None) -> int:
    """Run ``langctrl generalise``; returns the exit status."""
    return options.run_held_out("generalise", parse_args(argv), check_generalise, _run)


def _run(ns: argparse.Namespace, split: Any) -> str:
    text, n = run_generalise(ns, split)
    return f"{text}\nwrote {ns.out} ({n} episodes)"


if __name__ == "__main__":
    raise SystemExit(main())
