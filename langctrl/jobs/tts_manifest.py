"""``langctrl tts-manifest [--write]``: compare the shipped phrases' clips, synthesised into an
empty cache, with the committed manifest, or pin them (:mod:`langenv.speech.manifest`).

    langctrl tts-manifest            # compare fresh clips with the manifest
    langctrl tts-manifest --write    # pin the current clips (after a deliberate change)

Exit status 0 when they agree (or were written), 1 naming each difference (or when the clips
cannot be made), 2 on bad usage.
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
from collections.abc import Sequence

from langctrl import options
from langenv.errors import LangEnvError
from langenv.speech.manifest import MANIFEST_PATH, build, compare, load

__all__ = ["build_parser", "main"]


def build_parser() -> argparse.ArgumentParser:
    """The command line of ``langctrl tts-manifest`` (``python -m langctrl.jobs.tts_manifest``)."""
    p = options.job_parser(
        "tts-manifest",
        "Compare the shipped phrases' clips, synthesised into an empty cache, with the committed "
        "manifest; --write pins them instead.",
    )
    p.add_argument(
        "--write", action="store_true", help="write the manifest instead of comparing (off)"
    )
    return p


def main(argv: Sequence[str] | None = None) -> int:
    """Compare fresh clips with the manifest (exit 1 naming each difference), or ``--write``."""
    from langenv.speech import ClipLibrary

    args = build_parser().parse_args(argv)
    with tempfile.TemporaryDirectory(prefix="langctrl-tts-") as tmp:
        try:
            made = build(ClipLibrary(cache_dir=tmp))
        except LangEnvError as exc:
            return options.fail("tts-manifest", exc, 1)
    if args.write:
        MANIFEST_PATH.write_text(
            json.dumps(made, indent=1, ensure_ascii=False) + "\n", encoding="utf-8"
        )
        print(f"wrote {MANIFEST_PATH} ({len(made['clips'])} clips)")
        return 0
    problems = compare(made, load())
    for line in problems:
        print(f"{MANIFEST_PATH.name}: {line}", file=sys.stderr)
    print(f"{len(made['clips'])} clips, {len(problems)} differ from the manifest")
    return 1 if problems else 0


if __name__ == "__main__":
    raise SystemExit(main())
