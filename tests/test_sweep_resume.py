"""Nothing lost: a sweep killed part-way (SIGKILL to the driver, or to a worker) and resumed
gives exactly the rows of an uninterrupted sweep, without running a finished session again and
without a duplicate row."""

from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import pytest

from langctrl.jobs.sweep import main

ROOT = Path(__file__).resolve().parents[1]

SPEC = """\
grid:
  policy: [ac, lc]
  lc.k_c: [5.0, 10.0, 20.0]
users: {synthetic: 4, first_seed: 0}
"""
TOTAL = 4 + 3 * 4


def _parts(out: Path) -> list[Path]:
    rows = out / "rows"
    return sorted(rows.glob("part-*.parquet")) if rows.is_dir() else []


def _rows(out: Path) -> list[dict[str, Any]]:
    """Every row of every part (no de-duplication: a duplicate would show)."""
    import pyarrow.parquet as pq

    rows = [r for p in _parts(out) for r in pq.read_table(p).to_pylist()]
    return sorted(rows, key=lambda r: r["session_id"])


def _comparable(rows: list[dict[str, Any]]) -> list[str]:
    return [json.dumps(r, sort_keys=True, default=str) for r in rows]  # NaN == NaN as text


@pytest.fixture(scope="module")
def spec(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("spec") / "kill.yaml"
    path.write_text(SPEC)
    return path


@pytest.fixture(scope="module")
def reference(spec: Path) -> list[str]:
    out = spec.parent / "reference"
    assert main([str(spec), "--out", str(out), "--backend", "processes", "--workers", "1"]) == 0
    rows = _rows(out)
    assert len(rows) == TOTAL
    return _comparable(rows)


def _start(spec: Path, out: Path) -> subprocess.Popen[bytes]:
    cmd = [sys.executable, "-m", "langctrl", "sweep", str(spec), "--out", str(out)]
    cmd += ["--backend", "processes", "--workers", "2", "--batch-size", "1", "--no-summary"]
    return subprocess.Popen(
        cmd, cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, start_new_session=True
    )


def _wait_for_parts(proc: subprocess.Popen[bytes], out: Path, n: int) -> None:
    deadline = time.monotonic() + 300
    while len(_parts(out)) < n:
        assert proc.poll() is None, "the sweep ended before it could be killed"
        assert time.monotonic() < deadline, "no rows written in time"
        time.sleep(0.02)


def _children(pid: int) -> list[int]:
    kids: list[int] = []
    for task in Path(f"/proc/{pid}/task").iterdir():
        text = (task / "children").read_text().split()
        kids.extend(int(k) for k in text)
    return kids


def _end_group(proc: subprocess.Popen[bytes]) -> None:
    """End what is left of the process group this test started (orphaned workers)."""
    try:
        os.killpg(proc.pid, signal.SIGKILL)
    except ProcessLookupError:
        pass
    proc.wait(timeout=60)


def _resume(spec: Path, out: Path) -> dict[str, Any]:
    args = [str(spec), "--out", str(out), "--resume", "--backend", "processes", "--workers", "2"]
    assert main(args) == 0
    runs = [json.loads(line) for line in (out / "runs.jsonl").read_text().splitlines()]
    return runs[-1]


@pytest.mark.skipif(not Path("/proc/self/task").is_dir(), reason="finds workers through /proc")
def test_driver_killed_then_resumed(spec: Path, reference: list[str], tmp_path: Path) -> None:
    out = tmp_path / "sweep"
    proc = _start(spec, out)
    try:
        _wait_for_parts(proc, out, 3)
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait(timeout=60)
    finally:
        _end_group(proc)
    before = _rows(out)
    assert 3 <= len(before) < TOTAL
    run = _resume(spec, out)
    assert run["sessions"] == TOTAL - len(before)  # finished sessions are not run again
    assert _comparable(_rows(out)) == reference


@pytest.mark.skipif(not Path("/proc/self/task").is_dir(), reason="finds workers through /proc")
def test_worker_killed_then_resumed(spec: Path, reference: list[str], tmp_path: Path) -> None:
    out = tmp_path / "sweep"
    proc = _start(spec, out)
    try:
        _wait_for_parts(proc, out, 2)
        own = Path(f"/proc/{proc.pid}/cmdline").read_bytes()
        workers = [k for k in _children(proc.pid) if Path(f"/proc/{k}/cmdline").read_bytes() == own]
        assert workers, "no worker process found"
        os.kill(workers[0], signal.SIGKILL)
        proc.wait(timeout=300)  # the driver rebuilds its pool and goes on (or stops: resume)
        err = proc.stderr.read().decode() if proc.stderr else ""
    finally:
        _end_group(proc)
    assert "a worker died" in err, err
    _resume(spec, out)
    assert _comparable(_rows(out)) == reference


@pytest.mark.slow
@pytest.mark.skipif(not Path("/proc/self/task").is_dir(), reason="finds workers through /proc")
def test_ray_driver_killed_then_resumed(spec: Path, reference: list[str], tmp_path: Path) -> None:
    """The same on local Ray: the driver (and the Ray it started) killed, resumed on Ray."""
    out = tmp_path / "sweep"
    cmd = [sys.executable, "-m", "langctrl", "sweep", str(spec), "--out", str(out), "--no-summary"]
    cmd += ["--backend", "ray", "--workers", "2", "--batch-size", "1"]
    short = tempfile.mkdtemp(prefix="rk")  # the killed Ray's files go here (a short path)
    proc = subprocess.Popen(
        cmd,
        cwd=ROOT,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
        start_new_session=True,
        env={**os.environ, "TMPDIR": short},
    )
    try:
        _wait_for_parts(proc, out, 2)
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait(timeout=60)
    finally:
        _end_group(proc)  # Ray's processes started by the driver are in its group
        shutil.rmtree(short, ignore_errors=True)
    before = _rows(out)
    assert 2 <= len(before) < TOTAL
    args = [str(spec), "--out", str(out), "--resume", "--backend", "ray", "--workers", "2"]
    assert main(args) == 0
    assert _comparable(_rows(out)) == reference


def _ray_actors(group: int) -> list[int]:
    """Pids of the sweep's Ray actors (``ray::SweepWorker`` processes) whose parent (the
    raylet) is in process group ``group``: a local Ray started by the driver runs in the
    driver's group, its workers each in a session of their own."""
    found = []
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            cmdline = (entry / "cmdline").read_bytes()
            parent = int((entry / "stat").read_text().rsplit(")", 1)[1].split()[1])
            in_group = os.getpgid(parent) == group
        except (OSError, ProcessLookupError, ValueError, IndexError):
            continue
        if b"SweepWorker" in cmdline and in_group:
            found.append(int(entry.name))
    return found


@pytest.mark.slow
@pytest.mark.skipif(not Path("/proc/self/task").is_dir(), reason="finds workers through /proc")
def test_ray_worker_killed_is_replaced_and_nothing_lost(
    spec: Path, reference: list[str], tmp_path: Path
) -> None:
    """SIGKILL to one of local Ray's actors mid-sweep: Ray starts it again, its batches run
    again, and the sweep ends with exactly the uninterrupted rows (no resume needed)."""
    out = tmp_path / "sweep"
    cmd = [sys.executable, "-m", "langctrl", "sweep", str(spec), "--out", str(out), "--no-summary"]
    cmd += ["--backend", "ray", "--workers", "2", "--batch-size", "1"]
    short = tempfile.mkdtemp(prefix="rw")
    proc = subprocess.Popen(
        cmd,
        cwd=ROOT,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        start_new_session=True,
        env={**os.environ, "TMPDIR": short},
    )
    try:
        _wait_for_parts(proc, out, 2)
        actors = _ray_actors(proc.pid)
        assert actors, "no Ray actor found"
        os.kill(actors[0], signal.SIGKILL)
        _, err = proc.communicate(timeout=300)
    finally:
        _end_group(proc)
        shutil.rmtree(short, ignore_errors=True)
    assert proc.returncode == 0, err.decode()[-2000:]
    assert len(_parts(out)) >= 2
    assert _comparable(_rows(out)) == reference
