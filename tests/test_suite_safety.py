"""The test suite cannot hang: a crashed worker or a stalled test ends the run, naming the test.

Each case runs pytest in a subprocess over a small test file of its own, with this project's
pytest settings (``pyproject.toml``) and two xdist workers, as CI runs the suite.
"""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
LIMIT = 120
"""Seconds after which a run that has not ended is a hang: the test fails (how long the runs
take is not judged here)."""


def _run_pytest(tmp_path: Path, source: str, *options: str) -> subprocess.CompletedProcess[str]:
    (tmp_path / "test_victim.py").write_text(source)
    return subprocess.run(
        [
            sys.executable,
            "-m",
            "pytest",
            "-c",
            str(REPO / "pyproject.toml"),
            "--rootdir",
            str(tmp_path),
            "-p",
            "no:cacheprovider",
            "-n",
            "2",
            *options,
            str(tmp_path),
        ],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=LIMIT,  # a hang fails this test instead of hanging the suite
    )


def test_a_crashed_worker_ends_the_run_naming_the_test(tmp_path: Path) -> None:
    source = (
        "import os, signal\n\n"
        "def test_fine():\n    pass\n\n"
        "def test_crashes_its_worker():\n    os.kill(os.getpid(), signal.SIGSEGV)\n"
    )
    done = _run_pytest(tmp_path, source)
    out = done.stdout + done.stderr
    assert done.returncode != 0, out[-3000:]
    assert "test_crashes_its_worker" in out and "crashed" in out, out[-3000:]


def test_a_stalled_test_dumps_its_stack_and_ends_the_run(tmp_path: Path) -> None:
    source = "import time\n\ndef test_stalls():\n    time.sleep(600)\n"
    # the project's two limits (pyproject.toml), shortened: stacks at 2 s, the end at 4 s
    done = _run_pytest(tmp_path, source, "-o", "faulthandler_timeout=2", "-o", "timeout=4")
    out = done.stdout + done.stderr
    assert done.returncode != 0, out[-3000:]
    assert "Timeout" in out and 'test_victim.py", line 4 in test_stalls' in out, out[-3000:]
    assert "test_stalls" in out and "crashed" in out, out[-3000:]


def _handlers_that_catch_everything(tree: ast.AST) -> list[ast.ExceptHandler]:
    broad = {"Exception", "BaseException"}
    return [
        node
        for node in ast.walk(tree)
        if isinstance(node, ast.ExceptHandler)
        and (node.type is None or (isinstance(node.type, ast.Name) and node.type.id in broad))
    ]


def _installed_by_the_set_up() -> set[str]:
    """Top-level modules every install has: the project's packages and those of the
    distributions the README's set-up line installs (the dependencies and the dev, sweep and
    docs extras)."""
    import importlib.metadata as md
    import re
    import tomllib

    project = tomllib.loads((REPO / "pyproject.toml").read_text())["project"]
    wanted = list(project["dependencies"])
    for extra in ("dev", "sweep", "docs"):
        wanted += project["optional-dependencies"][extra]
    names = {re.split(r"[<>=\[; ]", req, maxsplit=1)[0].lower().replace("_", "-") for req in wanted}
    modules = {"langenv", "policies", "train", "eval", "bench", "langctrl"}
    for module, dists in md.packages_distributions().items():
        if any(d.lower().replace("_", "-") in names for d in dists):
            modules.add(module)
    return modules


def test_no_failure_of_ours_can_turn_into_a_skip() -> None:
    """A test skips only where the machine lacks a capability, probed apart from the project's
    code (conftest.offscreen_gl: an empty model): no test catches every exception (a bug of
    ours would pass as a skip), and none skips on importing a module every install has."""
    every_install = _installed_by_the_set_up()
    found = []
    for path in sorted((REPO / "tests").glob("*.py")):
        tree = ast.parse(path.read_text(encoding="utf-8"))
        for handler in _handlers_that_catch_everything(tree):
            if (path.name, handler.lineno) != ("conftest.py", _probe_line()):
                found.append(f"{path.name}:{handler.lineno}: catches every exception")
        for node in ast.walk(tree):
            if (
                isinstance(node, ast.Call)
                and isinstance(node.func, ast.Attribute)
                and node.func.attr == "importorskip"
                and node.args
                and isinstance(node.args[0], ast.Constant)
                and str(node.args[0].value).split(".")[0] in every_install
            ):
                found.append(f"{path.name}:{node.lineno}: importorskip({node.args[0].value!r})")
    assert found == []


def _probe_line() -> int:
    """The line of conftest.offscreen_gl's one broad handler (MuJoCo's GL errors vary)."""
    tree = ast.parse((REPO / "tests" / "conftest.py").read_text(encoding="utf-8"))
    probe = next(
        n for n in ast.walk(tree) if isinstance(n, ast.FunctionDef) and n.name == "offscreen_gl"
    )
    (handler,) = _handlers_that_catch_everything(probe)
    return handler.lineno
