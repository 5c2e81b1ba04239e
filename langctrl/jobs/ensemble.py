"""``langctrl ensemble``: write an ensemble manifest, several exported PPO models acting as one
(``ppo:OUT.yaml``; what it checks: :mod:`train.ensemble`).

    langctrl ensemble --out models/ppo_langctrl.yaml \\
        models/ppo_langctrl_s1000000.zip models/ppo_langctrl_s2000000.zip ...

Exit status 0 (the manifest's path printed), 2 on bad usage, an existing manifest without
``--overwrite`` or members that cannot act as one.
"""

from __future__ import annotations

import argparse
from collections.abc import Sequence
from pathlib import Path

from langctrl import options
from train.ensemble import EnsembleArgs, ensemble

__all__ = ["build_parser", "main", "parse_args"]


def build_parser() -> argparse.ArgumentParser:
    """The command line of ``langctrl ensemble`` (``python -m langctrl.jobs.ensemble``)."""
    p = options.job_parser(
        "ensemble",
        "Write an ensemble manifest: several exported PPO models acting as one (ppo:OUT.yaml).",
        options.out_file("the manifest (.yaml)"),
        options.overwrite("an existing manifest"),
    )
    p.add_argument(
        "models",
        type=Path,
        nargs="+",
        metavar="MODEL.zip",
        help="member model zips (langctrl export), in the manifest's folder",
    )
    return p


def parse_args(argv: Sequence[str] | None = None) -> EnsembleArgs:
    """Parse the command line into :class:`~train.ensemble.EnsembleArgs`."""
    p = build_parser()
    ns = p.parse_args(argv)
    if ns.out.suffix not in (".yaml", ".yml"):
        p.error(f"--out must end in .yaml, got {ns.out}")
    return options.args_of(EnsembleArgs, ns, models=tuple(ns.models))


def main(argv: Sequence[str] | None = None) -> int:
    """Run ``langctrl ensemble``; returns the exit status."""
    args = parse_args(argv)
    return options.run_job(
        "ensemble", lambda: ensemble(args), (FileNotFoundError, FileExistsError, ValueError)
    )


if __name__ == "__main__":
    raise SystemExit(main())
