"""The ``langctrl`` command: one entry point whose subcommands are LangCtrl's jobs.

``langctrl JOB ARGS...`` (or ``python -m langctrl JOB ARGS...``) imports the job's module, one
of :mod:`langctrl.jobs`, and calls its ``main(ARGS)``; the module's ``build_parser()`` is the
job's one parser, built on the shared options of :mod:`langctrl.options`, and names its program
``langctrl JOB``::

    langctrl compare --policies ac,lc-noap,lc --users synthetic:12 --seed 0 --out out/compare
    python -m langctrl compare --policies ac,lc-noap,lc --users synthetic:12 --out out/compare

The table :data:`COMMANDS` is the one place the jobs are listed; ``langctrl --help`` reads it
without importing any job.
"""

from __future__ import annotations

import argparse
import importlib
import sys
from collections.abc import Sequence
from dataclasses import dataclass
from importlib.metadata import PackageNotFoundError, version
from types import MappingProxyType, ModuleType

__all__ = ["COMMANDS", "Command", "build_parser", "load", "main"]


@dataclass(frozen=True)
class Command:
    """One job of ``langctrl``.

    Attributes:
        module: The job's module (``langctrl.jobs.NAME``); it defines ``build_parser()`` and
            ``main(argv) -> int``.
        summary: One line for ``langctrl --help``.
        group: ``"job"`` (a job of the toolkit) or ``"tool"`` (a helper of one).
    """

    module: str
    summary: str
    group: str = "job"


#: The subcommands, in the order ``langctrl --help`` lists them.
COMMANDS: MappingProxyType[str, Command] = MappingProxyType(
    {
        "compare": Command(
            "langctrl.jobs.compare", "compare policies on simulated or recorded users"
        ),
        "exercises": Command(
            "langctrl.jobs.exercises", "every shipped exercise under AC, LC-noAP and LC"
        ),
        "generalise": Command(
            "langctrl.jobs.generalise", "a learned model on held-out exercises and users"
        ),
        "fidelity": Command(
            "langctrl.jobs.fidelity", "the simulation against the recorded sessions"
        ),
        "coach-grid": Command(
            "langctrl.jobs.coach_grid", "coaches across a listening person's assumptions"
        ),
        "train": Command("langctrl.jobs.train", "train the learned aligner (SB3 PPO)"),
        "sweep": Command(
            "langctrl.jobs.sweep", "run a sweep of sessions from a YAML file, resumably"
        ),
        "play": Command(
            "langctrl.jobs.play", "live mode: drag the handle, the robot talks you through"
        ),
        "exercise": Command("langctrl.jobs.exercise", "list, check and draw exercises"),
        "speech": Command("langctrl.jobs.speech", "check, write and render phrase graphs"),
        "robot": Command("langctrl.jobs.robot", "run on a UR (or URSim) through ur-rtde"),
        "bench": Command("langctrl.jobs.bench", "speed and accuracy figures"),
        "export": Command(
            "langctrl.jobs.export", "a training checkpoint as a model (ppo:PATH)", "tool"
        ),
        "ensemble": Command("langctrl.jobs.ensemble", "several models acting as one", "tool"),
        "widen": Command("langctrl.jobs.widen", "a model for graphs with more choices", "tool"),
        "video": Command(
            "langctrl.jobs.video", "a session video (MP4) from an episode log", "tool"
        ),
        "report": Command("langctrl.jobs.report", "summary.md from a sessions.csv", "tool"),
        "calibrate": Command(
            "langctrl.jobs.calibrate", "fit the synthetic users to recordings", "tool"
        ),
        "listening": Command(
            "langctrl.jobs.listening", "fit the listening person's follow to AC", "tool"
        ),
        "voice-figure": Command(
            "langctrl.jobs.voice_figure", "the voice figure of a session's log", "tool"
        ),
        "tts-manifest": Command(
            "langctrl.jobs.tts_manifest", "the shipped phrases' clips against their pins", "tool"
        ),
        "bench-audio": Command("langctrl.jobs.bench_audio", "the vocoder's throughput", "tool"),
        "bench-memory": Command(
            "langctrl.jobs.bench_memory", "memory per session of the batched env", "tool"
        ),
        "bench-exercises": Command(
            "langctrl.jobs.bench_exercises", "what an exercise costs to load and follow", "tool"
        ),
        "bench-safety": Command(
            "langctrl.jobs.bench_safety", "fuzz the safety layer with adversarial users", "tool"
        ),
    }
)


def _listing() -> str:
    lines = []
    for group, title in (("job", "jobs"), ("tool", "tools")):
        lines.append(f"{title}:")
        for name, cmd in COMMANDS.items():
            if cmd.group == group:
                lines.append(f"  {name:16s} {cmd.summary}")
    lines.append("")
    lines.append("langctrl JOB --help: the job's options (python -m langctrl JOB: the same).")
    return "\n".join(lines)


def _version() -> str:
    try:
        return version("langctrl")
    except PackageNotFoundError:  # a source tree that was never installed
        return "unknown"


def build_parser() -> argparse.ArgumentParser:
    """The top-level parser: ``--help``, ``--version`` and the job's name (its arguments are the
    job's own, parsed by the job's parser)."""
    p = argparse.ArgumentParser(
        prog="langctrl",
        usage="%(prog)s [-h] [--version] JOB [ARGS...]",
        description="LangCtrl: a robot arm that moves and speaks in step with a person. One "
        "command for its jobs.",
        epilog=_listing(),
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("--version", action="version", version=f"%(prog)s {_version()}")
    p.add_argument(
        "job",
        metavar="JOB",
        choices=tuple(COMMANDS),
        help="the job to run (below), followed by its own arguments",
    )
    return p


def load(name: str) -> ModuleType:
    """The module of job ``name`` (``langctrl.jobs.NAME``)."""
    return importlib.import_module(COMMANDS[name].module)


def main(argv: Sequence[str] | None = None) -> int:
    """Run ``langctrl``; returns the exit status (the job's own, 2 for bad usage)."""
    args = list(sys.argv[1:] if argv is None else argv)
    if args and args[0] in COMMANDS:
        return int(load(args[0]).main(args[1:]) or 0)
    build_parser().parse_args(args)  # --help, --version or a usage error: exits
    return 2  # unreachable: the parser needs a JOB, and a known one is run above
