"""``langctrl bench-audio``: the variable-rate phase vocoder's throughput (``audio_rtf``,
:mod:`bench.audio`), at length. Exit status 0, 2 on bad usage."""

from __future__ import annotations

import argparse
from collections.abc import Sequence

from bench.audio import measure_audio_rtf
from langctrl import options

__all__ = ["build_parser", "main"]


def build_parser() -> argparse.ArgumentParser:
    """The command line of ``langctrl bench-audio`` (``python -m langctrl.jobs.bench_audio``)."""
    p = options.job_parser(
        "bench-audio",
        "Throughput of the variable-rate phase vocoder: seconds of speech rendered per second of "
        "wall time.",
    )
    p.add_argument(
        "--seconds", type=float, default=20.0, help="audio rendered, s (default: %(default)s)"
    )
    p.add_argument("--block", type=int, default=512, help="samples per pull (default: %(default)s)")
    p.add_argument(
        "--source",
        choices=["synthetic", "tts"],
        default="synthetic",
        help="speech-like noise or a synthesised phrase (default: %(default)s)",
    )
    return p


def main(argv: Sequence[str] | None = None) -> int:
    """Run ``langctrl bench-audio``; returns the exit status."""
    args = build_parser().parse_args(argv)
    rtf = measure_audio_rtf(args.seconds, block=args.block, source=args.source)
    print(f"audio_rtf {rtf:.1f} (block {args.block}, {args.source}, {args.seconds:g} s)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
