"""Every job takes the options it took before its command line moved into ``langctrl.jobs``.

``tests/data/job_options.json`` was written from the parsers as they stood before the move (the
jobs' parsers inside ``eval``, ``train``, ``bench`` and ``langenv``): for each job, each of its
parsers (subcommands included, keyed by their words after the job's name) and the option
strings of each argument (a positional as ``<dest>``), compared in any order (the shared options
come first now). A job may not lose, gain or rename an option by the move, nor change which
words it takes. Write the file again (after a deliberate change of an option) with::

    PYTHONPATH=. python -m tests.test_job_options --write
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from langctrl.cli import COMMANDS, load

FROZEN = Path(__file__).resolve().parent / "data" / "job_options.json"


def _parsers(
    parser: argparse.ArgumentParser, words: str = ""
) -> dict[str, argparse.ArgumentParser]:
    found = {words: parser}
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for name, sub in action.choices.items():
                found.update(_parsers(sub, f"{words} {name}".strip()))
    return found


def option_table(parser: argparse.ArgumentParser) -> dict[str, list[str]]:
    """Each parser of ``parser`` (by its subcommand words) -> its arguments' option strings."""
    return {
        words: [", ".join(a.option_strings) or f"<{a.dest}>" for a in p._actions]
        for words, p in _parsers(parser).items()
    }


def job_options() -> dict[str, dict[str, list[str]]]:
    """Every job of ``langctrl`` -> :func:`option_table` of its parser."""
    return {name: option_table(load(name).build_parser()) for name in COMMANDS}


def test_every_job_takes_the_options_it_took() -> None:
    frozen = json.loads(FROZEN.read_text(encoding="utf-8"))
    now = job_options()
    assert sorted(set(frozen) - set(now)) == [], "jobs gone"
    for name, table in frozen.items():
        assert {k: sorted(v) for k, v in now[name].items()} == {
            k: sorted(v) for k, v in table.items()
        }, name


if __name__ == "__main__":
    if sys.argv[1:] != ["--write"]:
        sys.exit("usage: PYTHONPATH=. python -m tests.test_job_options --write")
    FROZEN.write_text(json.dumps(job_options(), indent=1) + "\n", encoding="utf-8")
    print(f"wrote {FROZEN}")
