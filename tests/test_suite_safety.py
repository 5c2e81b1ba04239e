"""The test suite cannot hang: a crashed worker or a stalled test ends the run, naming the test.

Each case runs pytest in a subprocess over a small test file of its own, with this project's
pytest settings (``pyproject.toml``) and two xdist workers, as CI runs the suite.
"""

from __future__ import annotations

import subprocess
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
LIMIT = 60
"""Seconds within which the run must have ended."""


def _run_pytest(
    tmp_path: Path, source: str, *options: str
) -> tuple[subprocess.CompletedProcess[str], float]:
    (tmp_path / "test_victim.py").write_text(source)
    start = time.monotonic()
    done = subprocess.run(
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
        timeout=2 * LIMIT,  # a hang fails this test instead of hanging the suite
    )
    return done, time.monotonic() - start


def test_a_crashed_worker_ends_the_run_naming_the_test(tmp_path: Path) -> None:
    source = (
        "import os, signal\n\n"
        "def test_fine():\n    pass\n\n"
        "def test_crashes_its_worker():\n    os.kill(os.getpid(), signal.SIGSEGV)\n"
    )
    done, seconds = _run_pytest(tmp_path, source)
    out = done.stdout + done.stderr
    assert done.returncode != 0, out[-3000:]
    assert seconds < LIMIT, f"{seconds:.0f} s"
    assert "test_crashes_its_worker" in out and "crashed" in out, out[-3000:]


def test_a_stalled_test_dumps_its_stack_and_ends_the_run(tmp_path: Path) -> None:
    source = "import time\n\ndef test_stalls():\n    time.sleep(600)\n"
    # the project's two limits (pyproject.toml), shortened: stacks at 2 s, the end at 4 s
    done, seconds = _run_pytest(tmp_path, source, "-o", "faulthandler_timeout=2", "-o", "timeout=4")
    out = done.stdout + done.stderr
    assert done.returncode != 0, out[-3000:]
    assert seconds < LIMIT, f"{seconds:.0f} s"
    assert "Timeout" in out and 'test_victim.py", line 4 in test_stalls' in out, out[-3000:]
    assert "test_stalls" in out and "crashed" in out, out[-3000:]
