"""Command line: check a phrase graph, write one from a plain-text script, or render a
session's speech to a sound file.

    langctrl speech check GRAPH.yaml [--coverage]
    langctrl speech author SCRIPT.txt --out GRAPH.yaml
    langctrl speech render GRAPH.yaml TRACE.csv OUT.wav

Exit status 0 on success, 1 on a bad graph, trace or audio (messages on stderr), 2 on bad usage.
"""

from __future__ import annotations

import argparse
import csv
import math
import os
import sys
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from langctrl import options
from langenv.errors import LangEnvError, SessionDataError
from langenv.files import temp_file
from langenv.speech.audio import DEFAULT_RATE, DEFAULT_SR, DEFAULT_VOICE, ClipLibrary
from langenv.speech.author import author
from langenv.speech.coverage import coverage, format_coverage, speech_lengths
from langenv.speech.graph import SHIPPED_GRAPHS, PhraseGraph, graph_path
from langenv.speech.render import MAX_AUDIO_PACE, MIN_AUDIO_PACE
from langenv.speech.voice import VOICES
from langenv.validation import check_time_axis

_PROGRESS_AFTER = 5.0  # s of trace: longer renders show a progress bar (on a terminal)
_FORMATS = {".wav": ("WAV", "PCM_16"), ".flac": ("FLAC", "PCM_16")}


def build_parser() -> argparse.ArgumentParser:
    """The command line of ``langctrl speech`` (``python -m langctrl.jobs.speech``)."""
    p = options.job_parser(
        "speech",
        "Check LangCtrl phrase graphs, write one from a plain-text script, and render speech at a "
        "varying audio pace.",
        epilog="GRAPH is a phrase-graph YAML file (see docs/speech.md) or the name of a shipped "
        f"graph ({', '.join(sorted(SHIPPED_GRAPHS))}).",
    )
    tts = argparse.ArgumentParser(add_help=False)
    g = tts.add_argument_group("phrase audio (text-to-speech with eSpeak NG)")
    g.add_argument(
        "--sr", type=int, default=DEFAULT_SR, help="sample rate, Hz (default %(default)s)"
    )
    g.add_argument("--voice", default=DEFAULT_VOICE, help="eSpeak NG voice (default %(default)s)")
    g.add_argument(
        "--rate",
        type=int,
        default=DEFAULT_RATE,
        help="speaking rate, words/min (default %(default)s)",
    )
    g.add_argument(
        "--cache-dir",
        type=Path,
        default=None,
        help="TTS cache directory (default $LANGCTRL_CACHE or ~/.cache/langctrl/tts)",
    )
    g.add_argument("--no-cache", action="store_true", help="do not read or write the TTS cache")

    sub = p.add_subparsers(dest="command", required=True, metavar="{check,author,render}")
    c = sub.add_parser(
        "check",
        parents=[tts],
        help="validate a phrase graph and summarise it in one line",
        description="Validate a phrase graph (ids, cycles, dead ends, audio) and print one line: "
        "phrases, paths, and the shortest and longest speech at audio pace 1. Exit 1 with every "
        "problem on stderr when it is invalid.",
    )
    c.add_argument("graph", metavar="GRAPH", help="phrase graph YAML file or shipped graph name")
    c.add_argument(
        "--paths",
        action="store_true",
        help="also list every path with its length (each repeat said once)",
    )
    c.add_argument(
        "--coverage",
        action="store_true",
        help="also print the motion durations the speech can end together with",
    )

    w = sub.add_parser(
        "author",
        parents=[tts, options.out_file("phrase graph YAML"), options.overwrite("an existing OUT")],
        help="write a phrase graph from a plain-text script",
        description="Write the phrase graph of a plain-text script (one line per step; "
        "alternatives separated by '|', optional words in [...], pauses as (pause MIN-MAX), "
        "fillers as {okay|so}; see docs/speech.md), synthesise and time every clip, validate "
        "it, and print its coverage: the motion durations the speech can end together with at "
        "|a - 1| <= 0.1 and within the pace limits. Nothing is written unless the graph is valid.",
    )
    w.add_argument("script", metavar="SCRIPT", type=Path, help="plain-text script")
    w.add_argument(
        "--exercise",
        metavar="E",
        default=None,
        help="check the script's words against this exercise's motion times (a shipped name or "
        "an exercise YAML) and print 'warning:' lines where they fall short, and its @leg marks "
        "against the exercise's legs (an unknown leg is an error) (default: no check)",
    )

    r = sub.add_parser(
        "render",
        parents=[tts, options.overwrite("an existing OUT")],
        help="render the speech of a pace trace to a sound file",
        description="Render the speech a session says along a trace: a CSV with columns t (s), "
        "audio_pace and optionally t_x (s, the motion's time to completion; with it, phrases "
        "follow the paper's choice rule, without it the shortest path). Extra columns are "
        "ignored, so the study's session CSVs work as traces. OUT (.wav or .flac) is written "
        "only on success, and replaces an existing file only with --overwrite.",
    )
    r.add_argument("graph", metavar="GRAPH", help="phrase graph YAML file or shipped graph name")
    r.add_argument(
        "trace", metavar="TRACE", type=Path, help="CSV with columns t, audio_pace[, t_x]"
    )
    r.add_argument("out", metavar="OUT", type=Path, help="sound file to write (.wav or .flac)")
    r.add_argument("--no-t-x", action="store_true", help="ignore a t_x column: shortest path")
    r.add_argument(
        "--voicing",
        choices=VOICES,
        default=None,
        help="how the speech pace is voiced: time-stretched (the paper) or a natural voice that "
        "waits (default: the graph's 'voice')",
    )
    return p


def _graph_path(arg: str) -> Path:
    path = Path(arg)
    return path if path.exists() else graph_path(arg)


def read_trace(path: Path) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """Read a pace trace CSV: columns ``t``, ``audio_pace`` and optionally ``t_x``.

    Returns:
        ``(t, a, t_x)``, each of shape ``(n,)``; ``t_x`` is None without that column.

    Raises:
        SessionDataError: naming the file (and the column and row) when it is unreadable, lacks a
            column, has a non-numeric or non-finite value, a non-increasing ``t``, a span beyond
            ``MAX_SESSION_S`` (600 s) or samples closer than ``MIN_SAMPLE_SPACING`` (0.1 ms)
            (:mod:`langenv.validation`), a pace outside ``[MIN_AUDIO_PACE, MAX_AUDIO_PACE]``
            (0.25 to 4), or fewer than two rows.
    """
    try:
        with path.open(newline="", encoding="utf-8") as f:
            rows = list(csv.reader(f))
    except (OSError, UnicodeDecodeError) as exc:
        reason = getattr(exc, "strerror", None) or exc
        raise SessionDataError(f"{path}: cannot read trace: {reason}") from None
    rows = [r for r in rows if any(cell.strip() for cell in r)]
    if not rows:
        raise SessionDataError(f"{path}: empty trace (expected a header t,audio_pace[,t_x])")
    header = [h.strip() for h in rows[0]]
    for col in ("t", "audio_pace"):
        if col not in header:
            raise SessionDataError(f"{path}: missing column {col!r} (header: {header})")
    wanted = ["t", "audio_pace"] + (["t_x"] if "t_x" in header else [])
    cols = {name: header.index(name) for name in wanted}
    values = {name: np.empty(len(rows) - 1) for name in wanted}
    for i, row in enumerate(rows[1:]):
        for name, j in cols.items():
            cell = row[j].strip() if j < len(row) else ""
            try:
                v = float(cell)
            except ValueError:
                raise SessionDataError(
                    f"{path}: row {i + 2}, column {name!r}: not a number: {cell!r}"
                ) from None
            if not math.isfinite(v):
                raise SessionDataError(f"{path}: row {i + 2}, column {name!r}: not finite: {cell}")
            values[name][i] = v
    t, a = values["t"], values["audio_pace"]
    if t.size < 2:
        raise SessionDataError(f"{path}: a trace needs at least 2 rows, got {t.size}")
    bad = np.flatnonzero(np.diff(t) <= 0.0)
    if bad.size:
        raise SessionDataError(f"{path}: row {bad[0] + 3}, column 't': times must increase")
    check_time_axis(t, str(path), SessionDataError, lambda i: f"row {i + 2}", from_zero=False)
    bad = np.flatnonzero(a <= 0.0)
    if bad.size:
        raise SessionDataError(f"{path}: row {bad[0] + 2}, column 'audio_pace': must be > 0")
    bad = np.flatnonzero((a < MIN_AUDIO_PACE) | (a > MAX_AUDIO_PACE))
    if bad.size:
        raise SessionDataError(
            f"{path}: row {bad[0] + 2}, column 'audio_pace': {float(a[bad[0]])!r} is outside "
            f"[{MIN_AUDIO_PACE:g}, {MAX_AUDIO_PACE:g}]"
        )
    return t, a, values.get("t_x")


def _n(k: int, word: str) -> str:
    return f"{k} {word}" + ("" if k == 1 else "s")


def _clips(args: argparse.Namespace) -> ClipLibrary:
    return ClipLibrary(
        args.sr, args.cache_dir, voice=args.voice, rate=args.rate, disk_cache=not args.no_cache
    )


def _check(args: argparse.Namespace) -> int:
    graph = PhraseGraph.load(_graph_path(args.graph), _clips(args))
    if args.paths:
        once = bool(graph.repeats)  # every saying of every repeat: millions of paths
        for path in graph.paths(limit=100_000, once=once):
            lo, hi = graph.path_range(path)
            span = f"{lo:6.2f} s" if lo == hi else f"{lo:6.2f}-{hi:.2f} s"
            print(f"{span}  {' > '.join(path)}")
        if once:
            print(
                f"{_n(graph.count_paths(once=True), 'path')} with each repeat said once "
                f"({graph.count_paths()} with every saying of every repeat)"
            )
    print(_summary(graph))
    if args.coverage:
        print(format_coverage(coverage(graph)))
    return 0


def _summary(graph: PhraseGraph) -> str:
    own = graph.source_phrases.values()
    pauses = sum(ph.is_pause for ph in own)
    fillers = sum(ph.kind == "filler" for ph in own)
    kinds = [_n(len(own) - pauses - fillers, "phrase")]
    if fillers:
        kinds.append(_n(fillers, "filler"))
    if pauses:
        kinds.append(_n(pauses, "pause"))
    if graph.repeats:
        most = max(r.times for r in graph.repeats.values())
        kinds.append(f"{_n(len(graph.repeats), 'repeat')} (up to {most} times)")
    longest = speech_lengths(graph)[-1][1]
    repeats = f"; up to {longest:.2f} s with every repeat" if graph.repeats else ""
    ending = ", the last phrase waits for the motion" if graph.final_wait else ""
    legs = f", {_n(len(graph.legs), 'leg')} marked ({', '.join(graph.legs)})" if graph.legs else ""
    lo, hi = graph.speech_range()  # the whole speech (t_min/t_max of a marked graph: its leg's)
    return (
        f"{graph.path}: OK, {', '.join(kinds)}{legs}, {_n(graph.count_paths(), 'path')}, speech "
        f"{lo:.2f}-{hi:.2f} s at a = 1 "
        f"(shortest-longest, pause {graph.pause:g} s{repeats}), voice {graph.voice}{ending}"
    )


def _author(args: argparse.Namespace) -> int:
    out: Path = args.out
    if out.exists() and not args.overwrite:
        print(f"error: {out}: exists; give --overwrite to replace it", file=sys.stderr)
        return 1
    exercise = None
    if args.exercise is not None:
        from langenv.exercise import resolve_exercise

        # a bad exercise before anything is written; its script may be the one being written
        exercise = resolve_exercise(args.exercise, unwritten_scripts=True)
    legs = exercise.leg_names if exercise is not None else None
    _every_error(args.script)
    graph = author(args.script, out, _clips(args), legs)
    print(f"wrote {out} from {args.script}")
    print(_summary(graph))
    print(format_coverage(coverage(graph)))
    if exercise is None and not graph.legs:
        print(
            f"warning: {out.name}: no @leg marks: its words are aligned with the motion at its "
            "end only, not with each leg; mark each leg's lines ('@leg NAME' above them) to keep "
            "them in step"
        )
    if exercise is not None:
        from langenv.script_fit import fit_report

        print(f"against exercise {exercise.name}:")
        for line in fit_report(graph, exercise):
            print(line)
    return 0


def _every_error(script: Path) -> None:
    """Raise every error of the script at once (:func:`~langenv.speech.script_check.read_script`),
    not only its first; a file that cannot be read is left to ``author``, which names it."""
    from langenv.speech.script_check import read_script

    try:
        source = script.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError):
        return
    read_script(source, script)


def _render(args: argparse.Namespace) -> int:
    out: Path = args.out
    fmt = _FORMATS.get(out.suffix.lower())
    if fmt is None:
        print(
            f"error: {out}: unsupported output type; use one of {sorted(_FORMATS)}", file=sys.stderr
        )
        return 1
    if not out.parent.is_dir():
        print(f"error: {out}: directory {out.parent} does not exist", file=sys.stderr)
        return 1
    if out.exists() and not args.overwrite:
        print(f"error: {out}: exists; give --overwrite to replace it", file=sys.stderr)
        return 1
    clips = _clips(args)
    graph = PhraseGraph.load(_graph_path(args.graph), clips)
    if args.voicing is not None:
        graph = graph.with_voice(args.voicing)
    t, a, t_x = read_trace(args.trace)
    if args.no_t_x:
        t_x = None
    try:
        from langenv.speech.vocoder import VariableRateVocoder  # noqa: F401
    except ImportError as exc:
        print(f"error: rendering needs langenv.speech.vocoder: {exc}", file=sys.stderr)
        return 1
    from langenv.speech.render import plan_speech, render_history

    plan = plan_speech(graph, t, a, t_x)
    progress = None if t[-1] - t[0] > _PROGRESS_AFTER else False
    y = render_history(graph, clips, plan, t, a, progress=progress)
    y = np.clip(y, -1.0, 1.0)

    import soundfile as sf

    fd, tmp = temp_file(out.parent, prefix=f".{out.stem}.", suffix=out.suffix + ".part")
    os.close(fd)
    try:
        sf.write(tmp, y, clips.sr, format=fmt[0], subtype=fmt[1])
        os.replace(tmp, out)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    said = " > ".join(u.phrase if u.length is None else f"({u.length:.2f} s)" for u in plan)
    end = f"speech ends at {plan[-1].t_end:.2f} s" if plan else "nothing said"
    print(f"wrote {out}: {y.size / clips.sr:.2f} s at {clips.sr} Hz, {end}; said: {said}")
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line; returns the exit status."""
    args = build_parser().parse_args(argv)
    try:
        commands = {"check": _check, "author": _author, "render": _render}
        return commands[args.command](args)
    except (LangEnvError, OSError) as exc:
        return options.fail_lines(exc)


if __name__ == "__main__":
    sys.exit(main())
