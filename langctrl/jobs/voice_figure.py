"""``langctrl voice-figure LOG.npz --out F.png``: the voice figure of one session, what the
robot said against each clip's slot (:mod:`eval.voice_figure`).

    langctrl voice-figure out/main/sessions/lc_s3.npz --out natural_voice.png

Exit status 0, 2 on bad usage.
"""

from __future__ import annotations

import argparse
from collections.abc import Sequence

from eval.episode import EpisodeLog
from eval.voice_figure import voice_figure
from langctrl import options

__all__ = ["build_parser", "main"]


def build_parser() -> argparse.ArgumentParser:
    """The command line of ``langctrl voice-figure`` (``python -m langctrl.jobs.voice_figure``)."""
    return options.job_parser(
        "voice-figure",
        "The voice figure of one session from its episode log.",
        options.episode_log(),
        options.out_file("the PNG"),
    )


def main(argv: Sequence[str] | None = None) -> int:
    """Run ``langctrl voice-figure``; returns the exit status."""
    p = build_parser()
    ns = p.parse_args(argv)
    if not ns.out.parent.is_dir():
        p.error(f"--out {ns.out}: directory {ns.out.parent} does not exist")
    print(f"wrote {voice_figure(EpisodeLog.load_npz(ns.log), ns.out)}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
