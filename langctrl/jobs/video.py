"""``langctrl video LOG.npz --out F.mp4``: a session video (MP4, H.264 + AAC) from an episode
log (how: :mod:`eval.video`).

Exit status 0 (the video written), 2 on bad usage or a log it cannot render.
"""

from __future__ import annotations

import argparse
from collections.abc import Sequence
from pathlib import Path

from eval.episode import EpisodeLog
from eval.video import DEFAULT_FPS, session_audio, write_video
from langctrl import options
from langenv.errors import LangEnvError

__all__ = ["build_parser", "main"]


def build_parser() -> argparse.ArgumentParser:
    """The command line of ``langctrl video`` (``python -m langctrl.jobs.video``)."""
    p = options.job_parser(
        "video",
        "Render a session video (MP4, H.264 + AAC) from an episode log.",
        options.episode_log(),
        options.out_file("the .mp4"),
    )
    p.add_argument(
        "--fps",
        type=int,
        default=DEFAULT_FPS,
        help="frame rate, frames/s (default: %(default)s)",
    )
    p.add_argument(
        "--phrase-graph",
        default=None,
        metavar="GRAPH",
        help="the phrase graph spoken, a shipped key or a YAML (default: the one the log names)",
    )
    p.add_argument(
        "--model-path",
        type=Path,
        default=None,
        metavar="MJCF",
        help="the arm's MJCF (default: the shipped UR5)",
    )
    return p


def main(argv: Sequence[str] | None = None) -> int:
    """Run ``langctrl video``; returns the exit status."""
    args = build_parser().parse_args(argv)
    if args.out.suffix.lower() != ".mp4":
        return options.fail("video", f"--out must end in .mp4, got {args.out}")
    if not args.out.parent.is_dir():
        return options.fail("video", f"--out: no directory {args.out.parent}")
    try:
        log = EpisodeLog.load_npz(args.log)
        audio, sr = session_audio(log, args.phrase_graph)
        path = write_video(
            log, args.out, audio, sr, fps=args.fps, model_path=args.model_path, progress=None
        )
    except LangEnvError as exc:
        return options.fail("video", exc)
    print(f"wrote {path} ({len(log.utterances)} phrases, {log.t[-1] - log.t[0]:.1f} s)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
