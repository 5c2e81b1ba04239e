"""Sweep throughput: sessions per second with 1 and 2 local workers, and Ray's cost per session
against the process backend (``langctrl bench --only sweep``).

One small sweep (AC, LC-noAP and LC on :data:`USERS` synthetic users) runs through
``langctrl sweep``'s own code: the process backend with 1 worker and with 2, then Ray
(``--address local``) with 2, the process backend with 2 again and Ray again (the Ray figures
are means of its two runs against the means of the two process runs around them). Each figure
is the wall time of running the sessions as the driver records it in ``runs.jsonl`` (batches
run, parts written; the spec check, the kernels' warm-up, the backend's start and end not
counted). The backend's
one-off start (Ray: started, its actors warmed) and end (Ray shut down) are figures of their
own, and ``sweep_ray_overhead_total`` counts them too: what they cost this small sweep.

``session_cpu_s`` and ``overhead`` come from the workers: the CPU time of the batches per
session (which other programs on the machine stretch less than wall time), and the workers'
time outside batches (hand-off, idle at the end) over their time in batches.
``sweep_ray_thread_cpu`` is the CPU time a Ray actor's other threads (Ray's own: its RPCs,
its reports) spend during a batch, as a share of the sessions' thread, minus the same share in a
process worker: Ray's own CPU per session, which load on the machine hardly moves.

On a shared machine two processes do not get two cores: ``cpu_scaling`` is what this machine
gave a pure-Python loop in 2 processes against 1, measured just before, and
``sweep_scaling_efficiency`` the sweep's scaling as a share of it.
"""

from __future__ import annotations

import contextlib
import io
import json
import tempfile
from pathlib import Path

__all__ = ["USERS", "cpu_scaling", "measure_sweep"]

#: Synthetic users of the benchmark's sweep (3 sessions each).
USERS = 32


def _run(spec: Path, out: Path, backend: str, workers: int) -> dict[str, float]:
    """One sweep of ``spec`` into ``out`` (``langctrl sweep SPEC --out OUT --no-summary
    --backend B --workers W``'s arguments); its timing row."""
    from eval.sweep.driver import SweepArgs, run_sweep

    ns = SweepArgs(spec, out, workers, backend, no_summary=True)
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
        code = run_sweep(ns)
    if code != 0:
        raise RuntimeError(f"langctrl sweep exited with {code}")
    return json.loads((out / "runs.jsonl").read_text().splitlines()[-1])


def _burn(n: int) -> int:
    total = 0
    for i in range(n):
        total += i
    return total


def cpu_scaling(n: int = 20_000_000) -> float:
    """Throughput of a pure-Python loop in 2 processes over that in 1 (2.0 on 2 free cores)."""
    import multiprocessing
    import time

    t0 = time.perf_counter()
    _burn(n)
    one = time.perf_counter() - t0
    with multiprocessing.get_context().Pool(2) as pool:
        t0 = time.perf_counter()
        pool.map(_burn, [n, n])
        two = time.perf_counter() - t0
    return 2.0 * one / two


def measure_sweep(users: int = USERS) -> dict[str, float]:
    """``sweep_sps_1``, ``sweep_sps_2`` (sessions/s), ``sweep_scaling`` (their ratio),
    ``sweep_session_s`` (s per session, 1 worker) and, where Ray is installed, ``sweep_ray_sps_2``
    and ``sweep_ray_overhead`` (Ray's extra wall time per session over the process backend's, as
    a share of a session's time, both with 2 workers, start and end apart), the same in CPU time
    (``sweep_ray_overhead_cpu``), Ray's one-off ``sweep_ray_startup_s`` and
    ``sweep_ray_shutdown_s``, and ``sweep_ray_overhead_total`` (this sweep's whole time on Ray,
    start and end included, over the process backend's)."""
    import importlib.util

    figures: dict[str, float] = {"cpu_scaling": cpu_scaling()}
    with tempfile.TemporaryDirectory() as tmp:
        spec = Path(tmp) / "bench.yaml"
        spec.write_text(f"grid: {{policy: [ac, lc-noap, lc]}}\nusers: {{synthetic: {users}}}\n")
        one = _run(spec, Path(tmp) / "p1", "processes", 1)
        two = _run(spec, Path(tmp) / "p2", "processes", 2)
        figures["sweep_sps_1"] = one["sessions_per_s"]
        figures["sweep_sps_2"] = two["sessions_per_s"]
        figures["sweep_scaling"] = two["sessions_per_s"] / one["sessions_per_s"]
        figures["sweep_session_s"] = one["wall_s"] / one["sessions"]
        figures["sweep_scaling_efficiency"] = figures["sweep_scaling"] / figures["cpu_scaling"]
        figures["sweep_cpu_per_session_1"] = one["session_cpu_s"]
        figures["sweep_cpu_per_session_2"] = two["session_cpu_s"]
        figures["sweep_task_overhead_2"] = two["overhead"]
        if importlib.util.find_spec("ray") is not None:
            # Ray and the process backend in turn, twice (processes, Ray, processes, Ray): a
            # machine whose load drifts during the benchmark moves both sides alike.
            runs = [two]
            for k, backend in enumerate(("ray", "processes", "ray")):
                out = Path(tmp) / f"ab{k}"
                runs.append(_run(spec, out, backend, 2))
            procs, rays = runs[0::2], runs[1::2]

            def mean(rs: list[dict[str, float]], key: str) -> float:
                return sum(r[key] for r in rs) / len(rs)

            base, cpu = mean(procs, "wall_s"), mean(procs, "session_cpu_s")
            figures["sweep_ray_sps_2"] = mean(rays, "sessions_per_s")
            figures["sweep_ray_overhead"] = (mean(rays, "wall_s") - base) / base
            figures["sweep_ray_cpu_per_session"] = mean(rays, "session_cpu_s")
            figures["sweep_ray_overhead_cpu"] = (mean(rays, "session_cpu_s") - cpu) / cpu
            figures["sweep_ray_task_overhead"] = mean(rays, "overhead")

            def others(rs: list[dict[str, float]]) -> float:
                main = mean(rs, "session_thread_cpu_s")
                return (mean(rs, "session_cpu_s") - main) / main

            figures["sweep_ray_thread_cpu"] = others(rays) - others(procs)
            figures["sweep_ray_startup_s"] = mean(rays, "startup_s")
            figures["sweep_ray_shutdown_s"] = mean(rays, "shutdown_s")
            start = mean(procs, "startup_s")
            total = mean(rays, "wall_s") + mean(rays, "startup_s") + mean(rays, "shutdown_s")
            figures["sweep_ray_overhead_total"] = (total - base - start) / (base + start)
    return figures
