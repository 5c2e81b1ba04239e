"""The sweep's driver behind ``langctrl sweep SWEEP.yaml --out DIR``: run a sweep, resumably;
summarise it.

Run, for instance::

    langctrl sweep configs/sweeps/example.yaml --out out/sweep
    langctrl sweep configs/sweeps/example.yaml --out out/sweep --resume   # after a kill
    langctrl sweep configs/sweeps/example.yaml --out out/sweep --retry-failed
    langctrl sweep big.yaml --out out/big --backend ray --address auto    # on a cluster

Before any session runs, the file is checked whole (:func:`eval.sweep.spec.load_spec`) and
``DIR/sweep.yaml`` (the resolved file) and ``DIR/sweep.json`` (it, the code version and the
number of sessions) are written. Rows go to ``DIR/rows/part-*.parquet`` as batches finish
(:mod:`eval.sweep.store`); at the end ``DIR/summary.csv``, ``DIR/summary.md`` and
``DIR/plots/`` (:mod:`eval.sweep.summary`) are written from every row, and each run of the
driver appends its timing to ``DIR/runs.jsonl``.

Exit codes: 0 every session ok; 1 a bad sweep file or directory (nothing ran), or some sessions
failed (their rows hold the errors: ``--retry-failed`` runs them again); 2 bad arguments.
"""

from __future__ import annotations

import json
import math
import sys
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from eval.sweep.backend import make_backend
from eval.sweep.errors import SweepError
from eval.sweep.grid import SweepSession, expand
from eval.sweep.spec import COORDINATES, SweepSpec, load_spec

__all__ = ["MAX_BATCH", "SweepArgs", "batch_size", "run_sweep"]

#: Sessions per batch at most when the size is chosen: a batch takes a few seconds, so Ray's
#: few milliseconds per task stay far under 5 % of it, and a kill loses little work.
MAX_BATCH = 16


@dataclass(frozen=True)
class SweepArgs:
    """What a run of the sweep asks for (``langctrl sweep``'s arguments, by the same names).

    Attributes:
        spec: The sweep file.
        out: The sweep's directory.
        workers: Worker processes (Ray: the CPUs of a local Ray).
        backend: ``"processes"`` or ``"ray"``.
        address: Ray's address (``"local"``, ``"auto"`` or ``ray://HOST:PORT``).
        resume: Finish the sweep in ``out``.
        retry_failed: Run the failed sessions of ``out`` again.
        only: Run just these sessions (empty: every one).
        batch_size: Sessions per task (None: :func:`batch_size`'s choice).
        no_summary: Skip the summary and plots.
    """

    spec: Path
    out: Path
    workers: int
    backend: str
    address: str = "local"
    resume: bool = False
    retry_failed: bool = False
    only: Sequence[str] = field(default_factory=tuple)
    batch_size: int | None = None
    no_summary: bool = False

    @classmethod
    def of(cls, ns: Any) -> SweepArgs:
        """The arguments a parsed command line (an ``argparse.Namespace``) holds."""
        from dataclasses import fields

        return cls(**{f.name: getattr(ns, f.name) for f in fields(cls)})


def batch_size(n_sessions: int, workers: int, chosen: int | None = None) -> int:
    """Sessions per batch: ``chosen``, else enough batches for every worker to get 8, at most
    :data:`MAX_BATCH` sessions each."""
    if chosen is not None:
        return chosen
    return max(1, min(MAX_BATCH, math.ceil(n_sessions / (8 * workers))))


def _prepare(spec: SweepSpec, out: Path, sessions: list[SweepSession], resuming: bool) -> None:
    """Write the resolved spec and version into ``out`` (new), or check they match (resume)."""
    import yaml

    import langenv
    from eval.atomic import atomic_write

    meta = json.loads(json.dumps({"spec": spec.raw}))  # as it reads back
    record = out / "sweep.json"
    if record.exists():
        old = json.loads(record.read_text(encoding="utf-8"))
        if not resuming:
            raise SweepError(out, "", "holds a sweep already: give --resume to finish it")
        if old.get("spec") != meta["spec"]:
            raise SweepError(out, "", f"holds another sweep than {spec.file} (see its sweep.yaml)")
        if old.get("version") != langenv.__version__:
            print(
                f"langctrl sweep: warning: the sweep began with version {old.get('version')}, "
                f"this is {langenv.__version__} (each row records its own)",
                file=sys.stderr,
            )
        return
    if out.exists() and (not out.is_dir() or any(out.iterdir())):
        raise SweepError(out, "", "exists and is not an empty directory")
    out.mkdir(parents=True, exist_ok=True)
    meta.update(version=langenv.__version__, sessions=len(sessions), file=str(spec.file))
    atomic_write(out / "sweep.yaml", yaml.safe_dump(meta["spec"], sort_keys=False))
    atomic_write(out / "sweep.json", json.dumps(meta, indent=2) + "\n", durable=True)


def _todo(
    sessions: list[SweepSession], statuses: dict[str, str], ns: SweepArgs, out: Path
) -> list[SweepSession]:
    if ns.only:
        known = {s.session_id for s in sessions}
        unknown = [i for i in ns.only if i not in known]
        if unknown:
            raise SweepError(out, "--only", f"no session {', '.join(unknown)} in this sweep")
        return [s for s in sessions if s.session_id in set(ns.only)]

    def wanted(status: str | None) -> bool:  # no row yet, or a failed one to run again
        return status is None or (ns.retry_failed and status == "error")

    return [s for s in sessions if wanted(statuses.get(s.session_id))]


def run_sweep(ns: SweepArgs) -> int:
    """Run the sweep ``ns`` asks for and report it; the exit status."""
    from eval.sweep.store import SweepStore, row_schema

    t0 = time.perf_counter()
    out = ns.out.resolve()
    try:
        spec = load_spec(ns.spec)
        sessions = expand(spec)
        _prepare(spec, out, sessions, ns.resume or ns.retry_failed or bool(ns.only))
        store = SweepStore(out, row_schema(spec))
    except SweepError as exc:
        print(f"langctrl sweep: error: {exc}", file=sys.stderr)
        return 1
    try:
        todo = _todo(sessions, store.statuses(), ns, out)
        ran = _run(todo, store, ns, spec)
        if ns.only or ns.retry_failed:
            store.drop_superseded()
        rows = store.read().to_pylist()
    except SweepError as exc:
        print(f"langctrl sweep: error: {exc}", file=sys.stderr)
        return 1
    finally:
        store.close()
    return _report(rows, sessions, spec, ns, out, ran, time.perf_counter() - t0)


def _run(todo: list[SweepSession], store: Any, ns: SweepArgs, spec: SweepSpec) -> float:
    """Run ``todo`` in batches, a part file per batch; returns the seconds it took."""
    if not todo:
        return 0.0
    from tqdm import tqdm

    from langenv.batch.warm import warm_up
    from langenv.errors import LangEnvError

    warm_up()  # compiled once here: the workers load it, never compile it at once
    try:
        backend = make_backend(ns.backend, ns.workers, ns.address)
    except LangEnvError as exc:
        raise SweepError(ns.spec, "--backend", str(exc)) from None
    size = batch_size(len(todo), backend.workers, ns.batch_size or spec.batch_size)
    batches = [todo[i : i + size] for i in range(0, len(todo), size)]
    bar = tqdm(total=len(todo), desc="sessions", unit="s", file=sys.stderr)
    t0 = time.perf_counter()
    busy = cpu = thread = 0.0
    try:
        for _, result in backend.run(batches):
            store.write_part(result.rows)
            busy += result.wall_s
            cpu += result.cpu_s
            thread += result.thread_cpu_s
            bar.update(len(result.rows))
        wall = time.perf_counter() - t0
    finally:
        bar.close()
        t1 = time.perf_counter()
        backend.close()
        shutdown = time.perf_counter() - t1
    record = {
        "backend": ns.backend,
        "address": ns.address if ns.backend == "ray" else None,
        "workers": backend.workers,
        "batch_size": size,
        "sessions": len(todo),
        # The backend's one-off start (Ray: started or joined, its actors warmed) and end (Ray
        # shut down), not in wall_s.
        "startup_s": round(backend.startup_s, 3),
        "shutdown_s": round(shutdown, 3),
        "wall_s": round(wall, 3),
        "sessions_per_s": round(len(todo) / wall, 4),
        # Per session, in the workers: wall time and CPU time of the batches that ran it.
        "session_wall_s": round(busy / len(todo), 5),
        "session_cpu_s": round(cpu / len(todo), 5),
        "session_thread_cpu_s": round(thread / len(todo), 5),  # the sessions' thread alone
        # The workers' time not spent in batches (start-up, task hand-off, idle at the end) as a
        # share of the time spent in them.
        "overhead": round((backend.workers * wall - busy) / busy, 4),
        "time": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
    }
    with (store.root / "runs.jsonl").open("a", encoding="utf-8") as fh:
        fh.write(json.dumps(record) + "\n")
    return wall


def _report(
    rows: list[dict[str, Any]],
    sessions: list[SweepSession],
    spec: SweepSpec,
    ns: SweepArgs,
    out: Path,
    ran: float,
    wall: float,
) -> int:
    have = {r["session_id"] for r in rows}
    missing = [s.session_id for s in sessions if s.session_id not in have]
    failed = [r for r in rows if r["status"] != "ok"]
    if not ns.no_summary and rows:
        from eval.sweep.summary import write_summary

        coords = [*COORDINATES, "users", *spec.param_names]
        write_summary(rows, coords, out)
    print(
        f"langctrl sweep: {len(rows)}/{len(sessions)} sessions in {out} "
        f"({len(rows) - len(failed)} ok, {len(failed)} failed; {wall:.1f} s, sessions {ran:.1f} s)"
    )
    if missing:
        print(f"langctrl sweep: {len(missing)} sessions have no row yet: --resume runs them")
    for r in failed[:5]:
        last = (r["error"] or "").strip().splitlines()[-1:] or ["?"]
        print(f"  failed {r['session_id']} (seed {r['seed']}): {last[0]}", file=sys.stderr)
    if failed:
        print(
            "langctrl sweep: run them again with --retry-failed (or --only SESSION_ID)",
            file=sys.stderr,
        )
    return 1 if failed or missing else 0
