"""The figures in ``docs/results.md`` and ``README.md``, made and checked by running the jobs.

Each result in those pages sits between ``<!-- results: KEY -->`` and ``<!-- /results -->``: the
commands that give it (a ``bash`` block) and what they print or write (a ``text`` block for a
job's terminal output, a Markdown table for a section of a file it writes). :data:`SECTIONS`
holds, per key, the commands and what to show; this script runs them from the repository root
and writes the blocks (``--write``) or fails on any difference (``--check``), so a page cannot
show a figure the code no longer gives::

    python tools/results.py --list                  # the keys, their commands, what each needs
    python tools/results.py --check main            # the main job (about 10 s): CI runs this
    python tools/results.py --write                 # every section (about 4 min with 2 cores)
    python tools/results.py --write exercises fidelity

Commands run as shown (``langctrl`` is this interpreter's ``python -m langctrl``); each one's
``--out DIR`` under ``out/`` is removed first, so a rerun starts clean. ``--workdir DIR`` runs
them elsewhere (the tests do). A section whose ``needs`` path is missing (the study's recorded
sessions, ``../shared/sessions`` from where the commands run) is skipped with a note.
"""

from __future__ import annotations

import argparse
import re
import shlex
import shutil
import subprocess
import sys
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
PAGES = ("README.md", "docs/results.md", "docs/fidelity.md", "docs/scale.md", "docs/listening.md")
SESSIONS = "../shared/sessions"  # the study's recordings: not part of the repository

BLOCK = re.compile(
    r"(?P<open><!-- results: (?P<key>[\w-]+) -->\n).*?(?P<close><!-- /results -->)", re.DOTALL
)


@dataclass(frozen=True)
class Stdout:
    """A command's terminal output, from the first line matching ``start`` (default: the first
    line) to the one before the first matching ``stop`` (default: the last): as text, or as
    Markdown where the job prints a Markdown table."""

    command: int = 0
    start: str | None = None
    stop: str | None = None
    markdown: bool = False

    def extract(self, outputs: Sequence[str], workdir: Path) -> str:
        lines = outputs[self.command].strip("\n").splitlines()
        if self.start is not None:
            starts = [i for i, line in enumerate(lines) if re.match(self.start, line)]
            lines = lines[starts[0] :] if starts else []
        if self.stop is not None:
            ends = [i for i, line in enumerate(lines) if re.match(self.stop, line)]
            lines = lines[: ends[0]] if ends else lines
        text = "\n".join(line.rstrip() for line in lines) + "\n"
        return text if self.markdown else "```text\n" + text + "```\n"


@dataclass(frozen=True)
class FileSection:
    """The body of the section ``## HEADING...`` of a Markdown file a command wrote; of its table,
    the rows whose first cell is one of ``rows`` (default: every row)."""

    path: str
    heading: str
    rows: tuple[str, ...] = ()
    text: bool = False  # show it as text (a table Markdown would not read)

    def extract(self, outputs: Sequence[str], workdir: Path) -> str:
        text = (workdir / self.path).read_text(encoding="utf-8")
        parts = re.split(r"^## ", text, flags=re.MULTILINE)
        for part in parts[1:]:
            title, _, body = part.partition("\n")
            if title.startswith(self.heading):
                lines = body.strip("\n").splitlines()
                if self.rows:
                    lines = [ln for i, ln in enumerate(lines) if i < 2 or _cell(ln) in self.rows]
                body = "\n".join(lines) + "\n"
                return f"```text\n## {title}\n\n{body}```\n" if self.text else body
        raise SystemExit(f"{self.path}: no section '## {self.heading}'")


def _cell(line: str) -> str:
    """The first cell of a Markdown table row, unescaped."""
    if "|" not in line:
        return ""
    return re.split(r"(?<!\\)\|", line.strip().strip("|"))[0].strip().replace("\\|", "|")


@dataclass(frozen=True)
class Section:
    """One result: the commands, in order, and what of their output the pages show."""

    commands: tuple[str, ...]
    show: tuple[Stdout | FileSection, ...]
    needs: str | None = None  # a path the commands read that may be absent

    def render(self, outputs: Sequence[str], workdir: Path) -> str:
        shown = "\n".join(part.extract(outputs, workdir) for part in self.show)
        return "```bash\n" + "\n".join(self.commands) + "\n```\n\n" + shown


MAIN = "langctrl compare --policies ac,lc-noap,lc --users synthetic:12 --seed 0 --out out/compare"
VERDICT = Stdout(stop=r"^files:")
FINDINGLESS = Stdout(stop=r"^study's findings")  # runs without AC and LC-noAP: the medians only
#: The rows of a differences table the pages show: the paper's metrics, the voice, the length.
DIFF_ROWS = ("|AM| (s)", "mean |EM| (s)", "mean |a-1|", "voice natural (%)", "t_motion (s)")
PPO = "ppo:models/ppo_aligner.zip"
QUICK = "--no-audio --no-figures"
EXERCISES = "langctrl exercises --out out/exercises"  # 48 people per exercise and controller
#: The learned phrase chooser's test look (issue 44; the split's test people, 6 000 000 on, are
#: read from the model's config): the shipped model and its two seed siblings on the test
#: exercises x the 48 test people, perturbed and plain; a look at the test sets, recorded in
#: HISTORY.md (rerunning it gives the same figures).
SPEECH_LOOK = (
    "langctrl generalise --model models/ppo_speech.zip "
    "--model models/speech_seeds/ppo_speech_s1000000.zip "
    "--model models/speech_seeds/ppo_speech_s2000000.zip "
    "--role test --users 48 --population both --out out/speech_test"
)
SPEECH_MD = "out/speech_test/generalise.md"
#: The learned coach's test look (issue 46; the split's test people, 7 000 000 on, from
#: configs/ppo_coach.yaml): the shipped model and its two seed siblings with LC, lc-fill-end and
#: lc-coach at the 19 points of configs/coach_grid.yaml; a look, recorded in HISTORY.md.
COACH_LOOK = (
    "langctrl coach-grid --model models/ppo_coach.zip "
    "--model models/coach_seeds/ppo_coach_s3100000.zip "
    "--model models/coach_seeds/ppo_coach_s3200000.zip --out out/coach_grid"
)
SHIPPED = "ppo-ppo_speech"

#: The results, by key (a key may appear in several pages; its commands run once).
SECTIONS: dict[str, Section] = {
    "main": Section((MAIN,), (VERDICT,)),
    "main-summary": Section(
        (MAIN,), (FileSection("out/compare/summary.md", "Differences against LC", DIFF_ROWS),)
    ),
    "other-users": Section(
        tuple(
            f"langctrl compare --policies ac,lc-noap,lc --users synthetic:48 --seed {seed} "
            f"{QUICK} --out out/seed{seed}"
            for seed in (100, 200, 300)
        ),
        (Stdout(0, stop=r"^files:"), Stdout(1, stop=r"^files:"), Stdout(2, stop=r"^files:")),
    ),
    "replays": Section(
        (
            f"langctrl compare --policies ac,lc-noap,lc --sessions {SESSIONS} --pattern '*_lc.csv' "
            f"{QUICK} --out out/replays",
        ),
        (VERDICT,),
        needs=SESSIONS,
    ),
    "study-graph": Section(
        (
            f"langctrl compare --policies ac,lc-noap,lc --graph study {QUICK} --out out/study",
            f"langctrl compare --policies lc,lc-end,lc-em-end --graph study {QUICK} "
            "--out out/study_ext",
        ),
        (Stdout(0, stop=r"^files:"), Stdout(1, stop=r"^study's findings")),
    ),
    "exercises": Section(
        (EXERCISES,),
        (
            Stdout(start=r"^\| exercise \| controller", stop=r"^$", markdown=True),
            Stdout(start=r"^\| exercise \| LC sessions", markdown=True),
        ),
    ),
    "headline": Section(
        (EXERCISES,), (Stdout(start=r"^\| exercise \| LC sessions", markdown=True),)
    ),
    "learned-test": Section(
        (
            f"langctrl compare --policies lc,lc-em-end,{PPO} --graph study --users synthetic:48 "
            f"--seed 5000000 --stat mean {QUICK} --out out/test",
        ),
        (FINDINGLESS, FileSection("out/test/summary.md", "Differences against LC", DIFF_ROWS)),
    ),
    "learned-replays": Section(
        (
            f"langctrl compare --policies lc,lc-em-end,{PPO} --graph study --sessions {SESSIONS} "
            f"--pattern '*_lc.csv' --stat mean {QUICK} --out out/test_replays",
        ),
        (
            FINDINGLESS,
            FileSection("out/test_replays/summary.md", "Differences against LC", DIFF_ROWS),
        ),
        needs=SESSIONS,
    ),
    "speech-test": Section(
        (SPEECH_LOOK,),
        (
            FileSection(SPEECH_MD, "Every policy"),
            FileSection(SPEECH_MD, "The bars: "),
        ),
    ),
    "speech-headline": Section(
        (SPEECH_LOOK,),
        (
            FileSection(SPEECH_MD, "Every policy", ("lc", "lc-fill", "lc-fill-end", SHIPPED)),
            FileSection(SPEECH_MD, "The bars per group", (SHIPPED,)),
            FileSection(SPEECH_MD, "The bars: ", (SHIPPED,)),
        ),
    ),
    "coach-test": Section((COACH_LOOK,), (FileSection("out/coach_grid/grid.md", "The bars"),)),
    "fidelity": Section(
        (
            f"langctrl fidelity --sessions {SESSIONS} --users synthetic:48 --seed 2000 "
            "--out out/fidelity",
        ),
        (FileSection("out/fidelity/fidelity.md", "Checks"),),
        needs=SESSIONS,
    ),
}
SECTIONS["sweep"] = Section(
    ("langctrl sweep configs/sweeps/example.yaml --backend processes --out out/sweep",),
    tuple(
        FileSection("out/sweep/summary.md", coordinate, text=True)
        for coordinate in ("lc.k_c", "env.admittance.damping")
    ),
)
SECTIONS["fidelity-sessions"] = Section(
    SECTIONS["fidelity"].commands,
    (FileSection("out/fidelity/fidelity.md", "Sessions"),),
    needs=SESSIONS,
)


def _argv(command: str) -> list[str]:
    args = shlex.split(command)
    if args[0] == "langctrl":
        return [sys.executable, "-m", "langctrl", *args[1:]]
    return args


def _clear_out(args: Sequence[str], workdir: Path) -> None:
    """Remove the command's ``--out DIR`` when it lies under ``out/`` (never anything else)."""
    if "--out" in args:
        out = (workdir / args[list(args).index("--out") + 1]).resolve()
        if out.is_relative_to((workdir / "out").resolve()) and out.is_dir():
            shutil.rmtree(out)


def _prepare(workdir: Path) -> None:
    """A work directory other than the checkout gets links to what the commands read."""
    workdir.mkdir(parents=True, exist_ok=True)
    for name in ("configs", "langenv", "models"):
        if workdir.resolve() != REPO and not (workdir / name).exists():
            (workdir / name).symlink_to(REPO / name, target_is_directory=True)


def run(commands: Sequence[str], workdir: Path = REPO) -> list[str]:
    """Run the commands in ``workdir`` (the checkout by default); their standard outputs."""
    outputs = []
    for command in commands:
        args = _argv(command)
        _clear_out(args, workdir)
        print(f"$ {command}", file=sys.stderr, flush=True)
        res = subprocess.run(args, cwd=workdir, capture_output=True, text=True, check=False)
        if res.returncode not in (0, 1):  # 1: ran, and its verdict found a FAIL: still a result
            sys.stderr.write(res.stderr)
            raise SystemExit(f"{command}: exit status {res.returncode}")
        if res.returncode == 1:
            print(
                "  (exit status 1: its verdict failed; its output is shown as is)", file=sys.stderr
            )
        outputs.append(res.stdout)
    return outputs


def blocks(text: str) -> dict[str, str]:
    """The result blocks of a page: key -> its content between the markers."""
    return {m["key"]: text[m.end("open") : m.start("close")] for m in BLOCK.finditer(text)}


def _replace(text: str, rendered: dict[str, str]) -> str:
    def sub(m: re.Match[str]) -> str:
        body = rendered.get(m["key"])
        return m[0] if body is None else m["open"] + body + m["close"]

    return BLOCK.sub(sub, text)


def main(argv: Sequence[str] | None = None) -> int:
    p = argparse.ArgumentParser(
        prog="python tools/results.py", description=__doc__.split("\n\n")[0]
    )
    mode = p.add_mutually_exclusive_group(required=True)
    mode.add_argument("--check", action="store_true", help="fail on any difference (exit 1)")
    mode.add_argument("--write", action="store_true", help="rewrite the pages' result blocks")
    mode.add_argument("--list", action="store_true", help="print the keys and their commands")
    p.add_argument("keys", nargs="*", metavar="KEY", help="sections to run (default: all)")
    p.add_argument(
        "--workdir",
        type=Path,
        default=REPO,
        metavar="DIR",
        help="run the commands here, with links to the checkout's configs, langenv and models "
        "(default: the checkout)",
    )
    ns = p.parse_args(argv)
    unknown = sorted(set(ns.keys) - set(SECTIONS))
    if unknown:
        p.error(f"unknown keys {unknown}; known: {list(SECTIONS)}")
    pages = {page: (REPO / page).read_text(encoding="utf-8") for page in PAGES}
    used = {key for text in pages.values() for key in blocks(text)}
    if used - set(SECTIONS):
        p.error(f"the pages use keys this script does not know: {sorted(used - set(SECTIONS))}")
    if ns.list:
        for key, section in SECTIONS.items():
            where = [page for page, text in pages.items() if key in blocks(text)]
            need = f" (needs {section.needs})" if section.needs else ""
            print(f"{key}: in {', '.join(where) or 'no page'}{need}")
            for command in section.commands:
                print(f"    {command}")
        return 0
    workdir = ns.workdir.resolve()
    _prepare(workdir)
    rendered: dict[str, str] = {}
    done: dict[tuple[str, ...], list[str]] = {}
    for key in ns.keys or list(SECTIONS):
        section = SECTIONS[key]
        if section.needs and not (workdir / section.needs).exists():
            print(f"{key}: skipped, no {section.needs}", file=sys.stderr)
            continue
        if section.commands not in done:
            done[section.commands] = run(section.commands, workdir)
        rendered[key] = section.render(done[section.commands], workdir)
    status = 0
    for page, text in pages.items():
        if ns.write:  # the page as it is now: it may have been edited while the jobs ran
            text = (REPO / page).read_text(encoding="utf-8")
            new = _replace(text, rendered)
            if new != text:
                (REPO / page).write_text(new, encoding="utf-8")
                print(f"wrote {page}", file=sys.stderr)
            continue
        for key, body in blocks(text).items():
            if key in rendered and body != rendered[key]:
                import difflib

                diff = difflib.unified_diff(
                    body.splitlines(), rendered[key].splitlines(), page, "the code", lineterm=""
                )
                print(f"{page}: '{key}' differs from what the code gives:", file=sys.stderr)
                print("\n".join(diff), file=sys.stderr)
                status = 1
    return status


if __name__ == "__main__":
    sys.exit(main())
