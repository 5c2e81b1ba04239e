"""``langctrl compare``: compare aligners on simulated or recorded users, the study's evaluation.

    langctrl compare --policies ac,lc-noap,lc --users synthetic:12 --seed 0 --out out/compare
    langctrl compare --policies lc,ppo:models/ppo_aligner.zip \
        --sessions ../shared/sessions --pattern '*_lc.csv' --out out/replay

What it writes: :mod:`eval.compare`. Exit status 0 when every episode ran, 1 when ``--out`` was
taken while they ran (the outputs stay in a temporary directory beside it, named), 2 on bad
usage (nothing written).
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Sequence
from pathlib import Path

from eval.atomic import OutTaken
from eval.compare import CompareArgs, UsageError, run_compare, split_graphs
from langctrl import options

__all__ = ["build_parser", "main", "parse_args"]


def build_parser() -> argparse.ArgumentParser:
    """The command line of ``langctrl compare`` (``python -m langctrl.jobs.compare``)."""
    from langenv.live.registry import registered_policies

    p = options.job_parser(
        "compare",
        "Compare aligners (AC, LC-noAP, LC, learned) on simulated or recorded users: the study's "
        "evaluation.",
        options.users(None, unless="synthetic:12 unless --sessions is given"),
        options.listening(),
        options.seed(of="the first synthetic user (user i: SEED + i) and of the bootstrap"),
        options.out_dir("sessions.csv, summary.md, summary.png, sessions/, config.json"),
        options.overwrite("the outputs of an earlier run in a non-empty --out (other files stay)"),
        options.workers(),
        options.exercise(),
    )
    p.add_argument(
        "--policies",
        default=CompareArgs.policies,
        metavar="LIST",
        help=f"comma-separated policies: {', '.join(registered_policies())} (ppo:PATH: a learned "
        "model) (default: %(default)s)",
    )
    p.add_argument(
        "--sessions",
        type=Path,
        default=None,
        metavar="DIR",
        help="directory of recorded session CSVs (columns t in s, cooperation) to replay, one "
        "episode each, instead of --users (default: none)",
    )
    p.add_argument(
        "--pattern",
        default="*.csv",
        metavar="GLOB",
        help="glob of the session CSVs in --sessions (default: %(default)s)",
    )
    p.add_argument("--no-audio", action="store_true", help="skip WAV rendering")
    p.add_argument("--no-figures", action="store_true", help="skip per-session figures")
    p.add_argument(
        "--video",
        action="store_true",
        help="also write each session's video (MP4: the arm, traces, captions, the speech)",
    )
    p.add_argument(
        "--decision-hz",
        type=int,
        default=None,
        metavar="HZ",
        help="every policy's decision rate, Hz, a divisor of 500 (default: each policy's own)",
    )
    p.add_argument(
        "--graph",
        "--phrase-graph",
        dest="phrase_graph",
        action="append",
        default=None,
        metavar="[POLICY=]GRAPH",
        help="phrase graph for the policies that choose phrases (lc and its variants, ppo): a "
        "YAML file or a shipped graph ('study' is the study's graph); POLICY=GRAPH for one of "
        "them only (repeatable) (default: the exercise's script; AC and LC-noAP always say its "
        "one wording)",
    )
    p.add_argument(
        "--allow-mixed-graphs",
        action="store_true",
        help="compare phrase-choosing policies that speak different graphs (marked in the "
        "tables; default: refused)",
    )
    p.add_argument(
        "--stat",
        choices=("median", "mean"),
        default="median",
        help="statistic of the differences against LC in summary.md (default: %(default)s)",
    )
    return p


def parse_args(argv: Sequence[str] | None = None) -> CompareArgs:
    """Parse the command line into :class:`~eval.compare.CompareArgs`."""
    p = build_parser()
    ns = p.parse_args(argv)
    if ns.users is not None and ns.sessions is not None:
        p.error("give either --users or --sessions, not both")
    users = ns.users if ns.sessions is None else None
    if users is None and ns.sessions is None:
        users = "synthetic:12"
    try:
        graph, policy_graphs = split_graphs(ns.phrase_graph or [], ns.policies)
    except UsageError as exc:
        p.error(str(exc))
    return options.args_of(
        CompareArgs,
        ns,
        users=users,
        audio=not ns.no_audio,
        figures=not ns.no_figures,
        phrase_graph=graph,
        policy_graphs=policy_graphs,
    )


def main(argv: Sequence[str] | None = None) -> int:
    """Run ``langctrl compare``; returns the exit status."""
    args = parse_args(argv)
    t0 = time.perf_counter()
    try:
        out, labels, n = run_compare(args)
    except UsageError as exc:
        return options.fail("compare", exc)
    except OutTaken as exc:
        return options.fail("compare", exc, 1)
    print_verdict(out, labels, args)
    print(f"wrote {out} ({n} episodes in {time.perf_counter() - t0:.1f} s)")
    return 0


def print_verdict(out: Path, labels: list[str], args: CompareArgs) -> None:
    """The verdict on the terminal, read back from the ``sessions.csv`` just written."""
    from eval.report import read_sessions_csv
    from eval.verdict import print_verdict as verdict

    rows = read_sessions_csv(out / "sessions.csv")
    kinds = ["npz"]
    kinds += ["png"] if args.figures else []
    kinds += ["wav"] if args.audio else []
    kinds += ["mp4"] if args.video else []
    files = [
        ("sessions.csv", "one row per episode"),
        ("summary.md", "medians [IQR], intervals of the differences, the findings"),
        ("summary.png", "distributions per policy (violins)"),
        ("sessions/", "per episode <policy>_<user>: " + ", ".join(kinds)),
    ]
    present = {str(r["policy"]) for r in rows}
    verdict(rows, [n for n in labels if n in present], out, files)


if __name__ == "__main__":
    raise SystemExit(main())
