"""``langctrl export``: a checkpoint of a training run as a model ``PPOPolicy`` loads
(``ppo:PATH``; what it copies and checks: :mod:`train.export`).

    langctrl export runs/ppo --steps 100000 --out models/ppo_aligner
    langctrl export runs/ppo --best --out models/ppo_aligner   # chosen on validation

Exit status 0 (the model's path printed), 2 on bad usage, a missing checkpoint or an existing
``OUT`` without ``--overwrite``.
"""

from __future__ import annotations

import argparse
from collections.abc import Sequence
from pathlib import Path

from langctrl import options
from train.export import CONTENT_RULE, ExportArgs, export

__all__ = ["build_parser", "main", "parse_args"]


def build_parser() -> argparse.ArgumentParser:
    """The command line of ``langctrl export`` (``python -m langctrl.jobs.export``)."""
    p = options.job_parser(
        "export",
        "Export a checkpoint of a training run as a model PPOPolicy loads (ppo:PATH).",
        options.out_file(
            "stem of the exported model: STEM.zip, STEM_vecnormalize.pkl, STEM_config.yaml",
            metavar="STEM",
        ),
        options.overwrite("existing OUT.* files"),
    )
    p.add_argument("run", type=Path, metavar="RUN", help="the run directory of a langctrl train")
    which = p.add_mutually_exclusive_group(required=True)
    which.add_argument(
        "--steps", type=int, help="step count of the checkpoint (this or --best is required)"
    )
    which.add_argument(
        "--best",
        action="store_true",
        help="the checkpoint the periodic evaluations on the held-out users favour: for a phrase "
        f"chooser's run the {CONTENT_RULE}; for any other run the lowest mean |AM| + mean |EM| "
        "(not the run's best_return/, SB3's highest return)",
    )
    p.add_argument(
        "--name", default=None, help="the run's model name (default: train.name of its config)"
    )
    p.add_argument(
        "--choice-only",
        action="store_true",
        help="keep only the phrase-choice correction (the paces stay the base controller's)",
    )
    p.add_argument(
        "--terminal",
        type=float,
        default=None,
        metavar="S",
        help="give the exported model's base a terminal phase of S s (the shipped phrase "
        "chooser: 1, lc-fill-end's base; default: the run's)",
    )
    return p


def parse_args(argv: Sequence[str] | None = None) -> ExportArgs:
    """Parse the command line into :class:`~train.export.ExportArgs`."""
    return options.args_of(ExportArgs, build_parser().parse_args(argv))


def main(argv: Sequence[str] | None = None) -> int:
    """Run ``langctrl export``; returns the exit status."""
    args = parse_args(argv)
    return options.run_job(
        "export", lambda: export(args), (FileNotFoundError, FileExistsError, ValueError)
    )


if __name__ == "__main__":
    raise SystemExit(main())
