"""Write an ensemble manifest: several exported PPO models acting as one (``ppo:OUT.yaml``).

Run::

    python -m train.ensemble --out models/ppo_langctrl.yaml \\
        models/ppo_langctrl_s1000000.zip models/ppo_langctrl_s2000000.zip ...

The members (made with ``python -m train.export``) must lie in the manifest's folder and share
their residual design, decision rate, phrase graph and env arguments. The manifest records each
member's SHA-256 and is loaded once before it is written, so a broken ensemble fails here. An
existing manifest is replaced only with ``--overwrite``.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

__all__ = ["EnsembleArgs", "build_parser", "main", "parse_args"]


@dataclass(frozen=True)
class EnsembleArgs:
    """Arguments of ``python -m train.ensemble``.

    Attributes:
        models: The member model zips.
        out: The manifest to write (``.yaml``).
        overwrite: Replace an existing manifest.
    """

    models: tuple[Path, ...]
    out: Path
    overwrite: bool = False


def build_parser() -> argparse.ArgumentParser:
    """The command line of ``langctrl ensemble`` (``python -m train.ensemble``)."""
    p = argparse.ArgumentParser(
        prog="langctrl ensemble",
        description=__doc__.split("\n")[0] + " Also run as python -m train.ensemble.",
    )
    p.add_argument(
        "models",
        type=Path,
        nargs="+",
        metavar="MODEL.zip",
        help="member model zips (langctrl export), in the manifest's folder",
    )
    p.add_argument(
        "--out", type=Path, required=True, help="the manifest to write (.yaml; required)"
    )
    p.add_argument("--overwrite", action="store_true", help="replace an existing manifest")
    return p


def parse_args(argv: Sequence[str] | None = None) -> EnsembleArgs:
    """Parse the command line into :class:`EnsembleArgs`."""
    p = build_parser()
    ns = p.parse_args(argv)
    if ns.out.suffix not in (".yaml", ".yml"):
        p.error(f"--out must end in .yaml, got {ns.out}")
    return EnsembleArgs(models=tuple(ns.models), out=ns.out, overwrite=ns.overwrite)


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point; returns the process exit code."""
    from policies.ensemble import write_manifest

    args = parse_args(argv)
    if args.out.exists() and not args.overwrite:
        print(
            f"langctrl ensemble: error: {args.out} exists; give --overwrite to replace it",
            file=sys.stderr,
        )
        return 2
    try:
        path = write_manifest(args.out, list(args.models))
    except (FileNotFoundError, ValueError) as exc:
        print(f"langctrl ensemble: error: {exc}", file=sys.stderr)
        return 2
    print(path)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
