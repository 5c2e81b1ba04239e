"""``langctrl sweep SWEEP.yaml --out DIR``: run a sweep of sessions, resumably; summarise it
(what it writes: :mod:`eval.sweep.driver`).

    langctrl sweep configs/sweeps/example.yaml --out out/sweep
    langctrl sweep configs/sweeps/example.yaml --out out/sweep --resume   # after a kill
    langctrl sweep configs/sweeps/example.yaml --out out/sweep --retry-failed
    langctrl sweep big.yaml --out out/big --backend ray --address auto    # on a cluster

Exit status 0 every session ok; 1 a bad sweep file or directory (nothing ran), or some sessions
failed (their rows hold the errors: ``--retry-failed`` runs them again); 2 bad arguments.
"""

from __future__ import annotations

import argparse
import signal
import threading
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from eval.sweep.backend import SWEEP_BACKENDS, default_backend
from eval.sweep.driver import MAX_BATCH, SweepArgs, run_sweep
from langctrl import options

__all__ = ["build_parser", "main", "parse_args"]


def build_parser() -> argparse.ArgumentParser:
    """The command line of ``langctrl sweep`` (``python -m langctrl.jobs.sweep``)."""
    p = options.job_parser(
        "sweep",
        "Run a sweep (a grid or sample of sessions) resumably; summarise it.",
        options.out_dir("the sweep's rows, summary and plots"),
        options.workers(),
        more="With --backend ray, --workers is the CPUs of a local Ray (a cluster's own CPUs "
        "decide there).",
    )
    p.add_argument("spec", type=Path, metavar="SWEEP.yaml", help="the sweep file (YAML)")
    p.add_argument(
        "--resume", action="store_true", help="finish the sweep in --out (sessions with a row stay)"
    )
    p.add_argument(
        "--retry-failed", action="store_true", help="run the failed sessions of --out again"
    )
    p.add_argument(
        "--only",
        action="append",
        default=[],
        metavar="SESSION_ID",
        help="run just this session; repeat for more (default: every session)",
    )
    p.add_argument(
        "--backend",
        choices=tuple(SWEEP_BACKENDS),
        default=None,
        help="where sessions run (default: ray if installed, else processes)",
    )
    p.add_argument(
        "--address",
        default="local",
        help="Ray's address: local (start Ray here), auto (the cluster this process runs in) or "
        "ray://HOST:PORT (default: %(default)s)",
    )
    p.add_argument(
        "--batch-size",
        type=options.positive_int,
        default=None,
        metavar="N",
        help="sessions per task (default: the sweep file's batch_size, else 8 batches per "
        f"worker of at most {MAX_BATCH} sessions)",
    )
    p.add_argument("--no-summary", action="store_true", help="skip the summary and plots")
    return p


def parse_args(argv: Sequence[str] | None = None) -> argparse.Namespace:
    """The command line."""
    p = build_parser()
    ns = p.parse_args(argv)
    if ns.backend is None:
        ns.backend = default_backend()
    if ns.backend == "processes" and ns.address != "local":
        p.error("--address is Ray's: give --backend ray")
    return ns


def main(argv: Sequence[str] | None = None) -> int:
    """Run ``langctrl sweep``; returns the exit status."""
    ns = SweepArgs.of(parse_args(argv))
    if threading.current_thread() is not threading.main_thread():
        return run_sweep(ns)
    # SIGTERM (a scheduler's stop, `kill`) unwinds like Ctrl-C: the workers and a local Ray are
    # shut down, the parts written stay.
    previous = signal.signal(signal.SIGTERM, _terminate)
    try:
        return run_sweep(ns)
    finally:
        signal.signal(signal.SIGTERM, previous)


def _terminate(signum: int, frame: Any) -> None:
    raise SystemExit(128 + signum)


if __name__ == "__main__":
    raise SystemExit(main())
