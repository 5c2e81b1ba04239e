"""Sweeps run: the same rows for any backend, worker count and batch size; a failed session is a
row; ``--only`` / ``--retry-failed`` run sessions again without duplicating rows."""

from __future__ import annotations

import math
import multiprocessing
from pathlib import Path
from typing import Any

import pytest

from eval.compare import EPISODE_COLUMNS, Job, run_episode
from eval.sweep import expand, load_spec
from eval.sweep.backend import make_backend
from eval.sweep.store import SweepStore, row_schema
from langctrl.jobs.sweep import main

TINY = """\
grid:
  policy: [ac, lc]
  lc.k_c: [5.0, 20.0]
  env.admittance.damping: [70.0]
users: {synthetic: 2, first_seed: 3}
"""


def _rows(out: Path) -> list[dict[str, Any]]:
    import pyarrow.parquet as pq

    table = pq.read_table(out / "rows")
    return sorted(table.to_pylist(), key=lambda r: r["session_id"])


def _sweep(tmp_path: Path, name: str, *args: str, text: str = TINY) -> tuple[int, Path]:
    spec = tmp_path / "tiny.yaml"
    spec.write_text(text)
    out = tmp_path / name
    code = main([str(spec), "--out", str(out), "--no-summary", *args])
    return code, out


def _same(a: list[dict[str, Any]], b: list[dict[str, Any]]) -> None:
    """Equal rows, NaN equal to NaN (bit for bit: floats compared with ==)."""
    assert len(a) == len(b)
    for ra, rb in zip(a, b, strict=True):
        assert ra.keys() == rb.keys()
        for k in ra:
            va, vb = ra[k], rb[k]
            if isinstance(va, float) and math.isnan(va):
                assert isinstance(vb, float) and math.isnan(vb), k
            else:
                assert va == vb, (k, va, vb)


@pytest.fixture(scope="module")
def reference(tmp_path_factory: pytest.TempPathFactory) -> list[dict[str, Any]]:
    """The tiny sweep in this process, one batch after the other."""
    code, out = _sweep(
        tmp_path_factory.mktemp("ref"), "ref", "--backend", "processes", "--workers", "1"
    )
    assert code == 0
    return _rows(out)


def test_rows_hold_every_column(reference: list[dict[str, Any]], tmp_path: Path) -> None:
    assert len(reference) == 2 * 2 + 2  # lc: 2 gains x 2 users; ac: 2 users
    spec = load_spec_from(tmp_path)
    columns = row_schema(spec).names
    assert columns[: len(EPISODE_COLUMNS)] == list(EPISODE_COLUMNS)
    for extra in ("policy_spec", "exercise", "lc.k_c", "env.admittance.damping", "users", "seed"):
        assert extra in columns
    assert {r["status"] for r in reference} == {"ok"}
    spoken = {(r["policy"], r["graph"], r["graph_role"]) for r in reference}
    assert spoken == {("ac", "lc-noap", "single"), ("lc", "default", "graph")}  # what each spoke
    assert {r["version"] for r in reference} == {__import__("langenv").__version__}
    ac = [r for r in reference if r["policy"] == "ac"]
    assert all(r["lc.k_c"] is None and r["env.admittance.damping"] == 70.0 for r in ac)
    assert len({r["session_id"] for r in reference}) == len(reference)


def load_spec_from(tmp_path: Path) -> Any:
    path = tmp_path / "tiny.yaml"
    path.write_text(TINY)
    return load_spec(path)


def test_a_row_is_the_episode_of_eval_compare(reference: list[dict[str, Any]]) -> None:
    """A sweep's row equals run_episode's for that policy, user, seed and parameters."""
    row = next(
        r for r in reference if r["policy"] == "lc" and r["lc.k_c"] == 20.0 and r["user"] == "s4"
    )
    job = Job(
        "lc", "s4", 4, None, "", False, False, None,
        params=(("gains.k_c", 20.0),), env_params=(("admittance.damping", 70.0),), save_log=False,
    )  # fmt: skip
    episode = run_episode(job)
    assert set(episode) == set(EPISODE_COLUMNS)  # every column of sessions.csv is in the rows
    for column in EPISODE_COLUMNS:
        assert episode[column] == row[column] or (
            isinstance(row[column], float)
            and math.isnan(row[column])
            and math.isnan(episode[column])
        ), column
    baseline = run_episode(Job("lc", "s4", 4, None, "", False, False, None, save_log=False))
    assert baseline["am"] != row["am"]  # the parameters did act


def test_two_workers_and_batches_of_one_give_the_same_rows(
    reference: list[dict[str, Any]], tmp_path: Path
) -> None:
    code, out = _sweep(
        tmp_path, "n2", "--backend", "processes", "--workers", "2", "--batch-size", "1"
    )
    assert code == 0
    _same(_rows(out), reference)


def test_ray_gives_the_same_rows(reference: list[dict[str, Any]], tmp_path: Path) -> None:
    code, out = _sweep(tmp_path, "ray", "--backend", "ray", "--workers", "2", "--batch-size", "2")
    assert code == 0
    _same(_rows(out), reference)
    import ray

    assert not ray.is_initialized()  # shut down at the end


def test_ray_missing_is_named(monkeypatch: pytest.MonkeyPatch) -> None:
    import sys

    from langenv.errors import DeviceError

    monkeypatch.setitem(sys.modules, "ray", None)  # import ray -> ImportError
    with pytest.raises(DeviceError, match=r'pip install -e "\.\[sweep\]"'):
        make_backend("ray", 1)


def test_unknown_backend_is_named() -> None:
    from langenv.errors import ConfigError

    with pytest.raises(ConfigError, match="known: processes, ray"):
        make_backend("slurm", 1)


def _fails_for_s4(job: Job) -> dict[str, Any]:
    if job.user == "s4" and job.policy == "lc":
        raise RuntimeError("injected failure")
    return run_episode(job)


@pytest.mark.skipif(
    multiprocessing.get_start_method() != "fork", reason="the patch reaches forked workers only"
)
def test_a_failed_session_is_a_row_and_runs_again_alone(
    reference: list[dict[str, Any]], tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    import eval.compare

    with monkeypatch.context() as m:
        m.setattr(eval.compare, "run_episode", _fails_for_s4)
        code, out = _sweep(
            tmp_path, "f", "--backend", "processes", "--workers", "2", "--batch-size", "3"
        )
    assert code == 1  # some failed
    rows = _rows(out)
    failed = [r for r in rows if r["status"] == "error"]
    assert len(rows) == len(reference) and len(failed) == 2
    assert all("injected failure" in r["error"] and r["seed"] == 4 for r in failed)
    assert all(math.isnan(r["am"]) for r in failed)
    ok = [r for r in rows if r["status"] == "ok"]
    _same(ok, [r for r in reference if r["session_id"] in {o["session_id"] for o in ok}])
    # One alone, then the rest: no duplicate row at any point.
    again = [str(tmp_path / "tiny.yaml"), "--out", str(out), "--workers", "1"]
    again += ["--backend", "processes"]
    code = main([*again, "--no-summary", "--only", failed[0]["session_id"]])
    assert code == 1  # the other one still failed
    rows = _rows(out)
    assert len(rows) == len(reference) and sum(r["status"] == "error" for r in rows) == 1
    code = main([*again, "--retry-failed"])
    assert code == 0
    _same(_rows(out), reference)
    assert (out / "summary.md").exists() and (out / "plots" / "lc.k_c.png").exists()


def test_resume_refuses_another_sweep_and_a_taken_dir(tmp_path: Path) -> None:
    code, out = _sweep(
        tmp_path,
        "x",
        "--backend",
        "processes",
        "--workers",
        "1",
        text=TINY.replace("synthetic: 2", "synthetic: 1"),
    )
    assert code == 0
    assert main([str(tmp_path / "tiny.yaml"), "--out", str(out), "--workers", "1"]) == 1
    other = tmp_path / "other.yaml"
    other.write_text(TINY)
    assert main([str(other), "--out", str(out), "--resume", "--workers", "1"]) == 1
    import subprocess
    import sys

    store = SweepStore(out, None)  # a driver holds the directory: a second one is refused
    try:
        cmd = [
            sys.executable,
            "-m",
            "langctrl",
            "sweep",
            str(tmp_path / "tiny.yaml"),
            "--out",
            str(out),
        ]
        proc = subprocess.run(
            [*cmd, "--resume", "--backend", "processes"],
            cwd=Path(__file__).resolve().parents[1],
            capture_output=True,
            text=True,
            timeout=120,
            check=False,
        )
    finally:
        store.close()
    assert proc.returncode == 1 and "another langctrl sweep is running" in proc.stderr, proc.stderr


def test_expansion_matches_the_rows(reference: list[dict[str, Any]], tmp_path: Path) -> None:
    sessions = expand(load_spec_from(tmp_path))
    assert sorted(s.session_id for s in sessions) == [r["session_id"] for r in reference]


def test_import_needs_neither_ray_nor_pyarrow() -> None:
    import subprocess
    import sys

    code = (
        "import sys; sys.modules['ray'] = None; import eval.sweep, eval.sweep.driver; "
        "import langctrl.jobs.sweep; "
        "assert 'pyarrow' not in sys.modules, 'pyarrow imported'"
    )
    root = Path(__file__).resolve().parents[1]
    proc = subprocess.run(
        [sys.executable, "-c", code], cwd=root, capture_output=True, text=True, timeout=120
    )
    assert proc.returncode == 0, proc.stderr
