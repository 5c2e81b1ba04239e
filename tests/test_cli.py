"""The ``langctrl`` command: every job behind one entry point, each with one parser.

``langctrl JOB --help`` must print exactly what ``python -m MODULE --help`` prints, every option
of every job must say what it does and (where it takes a value) its default, and ``langctrl
--help`` must list the jobs without importing any of them.
"""

from __future__ import annotations

import argparse
import os
import runpy
import shutil
import subprocess
import sys
import warnings
from pathlib import Path

import pytest

from langctrl.cli import COMMANDS, load, main

REPO = Path(__file__).resolve().parents[1]

#: The jobs issue 40 names; `langctrl` may have more (its tools), never fewer.
ISSUE_JOBS = (
    "compare",
    "exercises",
    "generalise",
    "fidelity",
    "train",
    "sweep",
    "play",
    "exercise",
    "speech",
    "robot",
    "bench",
)


@pytest.fixture(autouse=True)
def _fixed_width(monkeypatch: pytest.MonkeyPatch) -> None:
    """argparse wraps help to the terminal's width: the same for both ways of asking."""
    monkeypatch.setenv("COLUMNS", "100")


def _help(run: object) -> str:
    """What ``run()`` prints before exiting 0 (argparse's ``--help`` exits)."""
    from contextlib import redirect_stdout
    from io import StringIO

    buf = StringIO()
    with redirect_stdout(buf), pytest.raises(SystemExit) as info:
        run()  # type: ignore[operator]
    assert info.value.code == 0
    return buf.getvalue()


def test_help_lists_every_job() -> None:
    text = _help(lambda: main(["--help"]))
    for name, cmd in COMMANDS.items():
        assert f"  {name} " in text and f"python -m {cmd.module} " in text + " "
    assert set(ISSUE_JOBS) <= set(COMMANDS)


@pytest.mark.parametrize("name", list(COMMANDS))
def test_job_help_equals_python_m_help(name: str, monkeypatch: pytest.MonkeyPatch) -> None:
    """``langctrl JOB --help`` == ``python -m MODULE --help``: runpy runs the module as
    ``python -m`` does (``__main__``, the package's ``__main__`` for a package)."""
    module = COMMANDS[name].module
    ours = _help(lambda: main([name, "--help"]))
    monkeypatch.setattr(sys, "argv", [module, "--help"])
    with warnings.catch_warnings():  # the module is imported already: runpy says so
        warnings.simplefilter("ignore", RuntimeWarning)
        theirs = _help(lambda: runpy.run_module(module, run_name="__main__", alter_sys=True))
    assert ours == theirs
    assert ours.startswith(f"usage: langctrl {name} ")


@pytest.mark.parametrize("name", list(COMMANDS))
def test_one_parser_per_job(name: str) -> None:
    """The module's own ``build_parser()`` is the job's parser; it names ``python -m``."""
    module = load(name)
    parser = module.build_parser()
    assert parser.prog == f"langctrl {name}"
    assert f"python -m {COMMANDS[name].module}" in (parser.description or "")


def _parsers(parser: argparse.ArgumentParser) -> list[argparse.ArgumentParser]:
    found = [parser]
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for sub in action.choices.values():
                found += _parsers(sub)
    return found


def _undocumented(parser: argparse.ArgumentParser) -> list[str]:
    """Options without a help text, and options taking a value whose help gives no default."""
    required_groups = {
        id(a) for g in parser._mutually_exclusive_groups if g.required for a in g._group_actions
    }
    bad = []
    for action in parser._actions:
        name = "/".join(action.option_strings) or action.metavar or action.dest
        if isinstance(action, argparse._SubParsersAction):
            bad += [f"{c.dest}: no help" for c in action._choices_actions if not c.help]
            continue
        if isinstance(action, argparse._HelpAction | argparse._VersionAction):
            continue
        text = action.help
        if not text or text == argparse.SUPPRESS:
            bad.append(f"{name}: no help")
            continue
        takes_value = action.option_strings and action.nargs != 0
        optional = not action.required and id(action) not in required_groups
        if takes_value and optional and "default" not in text:
            bad.append(f"{name}: help gives no default")
    return [f"{parser.prog} {b}" for b in bad]


@pytest.mark.parametrize("name", list(COMMANDS))
def test_every_option_says_what_it_does_and_its_default(name: str) -> None:
    bad = [b for p in _parsers(load(name).build_parser()) for b in _undocumented(p)]
    assert bad == []


def test_the_check_finds_an_undocumented_option() -> None:
    p = argparse.ArgumentParser(prog="x")
    p.add_argument("--a", type=int, default=3)
    p.add_argument("--b", type=int, default=3, help="b, s")
    p.add_argument("--c", type=int, default=3, help="c, s (default: %(default)s)")
    p.add_argument("--d", action="store_true", help="d")
    p.add_argument("--e", required=True, help="e")
    assert _undocumented(p) == ["x --a: no help", "x --b: help gives no default"]


def test_job_exit_status_passes_through(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["exercise", "check", "no_such_exercise"]) == 2  # the module's own usage error
    assert "external_rotation" in capsys.readouterr().err
    with pytest.raises(SystemExit) as info:
        main(["no_such_job"])
    assert info.value.code == 2
    assert "invalid choice" in capsys.readouterr().err


def test_top_level_help_imports_no_job() -> None:
    """``langctrl --help`` stays fast: it reads the table, not the modules."""
    code = (
        "import sys\n"
        "from langctrl.cli import main\n"
        "try:\n    main(['--help'])\nexcept SystemExit:\n    pass\n"
        "loaded = sorted(m for m in sys.modules if m.split('.')[0] in "
        "{'langenv', 'policies', 'train', 'eval', 'bench', 'numpy'})\n"
        "print('LOADED', loaded, file=sys.stderr)\n"
    )
    res = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, cwd=REPO, check=True
    )
    assert "LOADED []" in res.stderr


def test_console_script_runs_the_jobs() -> None:
    """The installed ``langctrl`` (the README's set-up line installs it) and ``python -m``."""
    script = shutil.which("langctrl", path=str(Path(sys.executable).parent))
    assert script is not None, "no langctrl script: run the README's pip install line again"
    env = dict(os.environ, COLUMNS="100")
    run = dict(capture_output=True, text=True, cwd=REPO, env=env, check=False, timeout=120)
    top = subprocess.run([script, "--help"], **run)  # type: ignore[call-overload]
    assert top.returncode == 0 and all(f"  {job} " in top.stdout for job in ISSUE_JOBS)
    ours = subprocess.run([script, "exercise", "--help"], **run)  # type: ignore[call-overload]
    theirs = subprocess.run(  # type: ignore[call-overload]
        [sys.executable, "-m", "langctrl.jobs.exercise", "--help"], **run
    )
    assert ours.returncode == theirs.returncode == 0
    assert ours.stdout == theirs.stdout
    module = subprocess.run(  # type: ignore[call-overload]
        [sys.executable, "-m", "langctrl", "exercise", "list"], **run
    )
    assert module.returncode == 0 and "external_rotation" in module.stdout


def test_no_message_names_a_python_module_for_a_command() -> None:
    """An error (or a note) says the command the user typed, ``langctrl compare: error``, not
    the module behind it (``eval.compare: error``)."""
    import re

    prefix = re.compile(r"f?[\"'](eval|train|langenv|policies|bench)(\.[a-z_]+)+: ")
    found = []
    for package in ("eval", "train", "langenv", "policies", "bench"):
        for path in sorted((REPO / package).rglob("*.py")):
            for i, line in enumerate(path.read_text(encoding="utf-8").splitlines(), start=1):
                if prefix.search(line):
                    found.append(f"{path.relative_to(REPO)}:{i}: {line.strip()}")
    assert found == []


@pytest.mark.parametrize(
    ("name", "args"),
    [
        ("compare", ["--policies", "no_such_policy", "--users", "synthetic:1"]),
        ("export", ["no_such_run", "--steps", "1", "--out", "x"]),
        ("exercise", ["check", "no_such_exercise"]),
    ],
)
def test_a_job_s_error_names_the_command(
    name: str, args: list[str], capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    if name == "compare":
        args = [*args, "--out", str(tmp_path / "out")]
    assert main([name, *args]) != 0
    assert capsys.readouterr().err.startswith(f"langctrl {name}: error: ")
