"""Sweep throughput: sessions per second with 1 and 2 local workers, and Ray's cost per session
against the process backend (``python -m bench --only sweep``).

One small sweep (AC, LC-noAP and LC on :data:`USERS` synthetic users) runs three times through
``python -m eval.sweep``'s own code: the process backend with 1 worker and with 2, then Ray
(``--address local``) with 2. Each figure is the wall time of running the sessions as the driver
records it in ``runs.jsonl`` (workers started, batches run, parts written; the spec check, the
kernels' warm-up and Ray's own start-up not counted).
"""

from __future__ import annotations

import contextlib
import io
import json
import tempfile
from pathlib import Path

__all__ = ["USERS", "measure_sweep"]

#: Synthetic users of the benchmark's sweep (3 sessions each).
USERS = 16


def _run(spec: Path, out: Path, *args: str) -> dict[str, float]:
    from eval.sweep.__main__ import main

    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
        code = main([str(spec), "--out", str(out), "--no-summary", *args])
    if code != 0:
        raise RuntimeError(f"eval.sweep exited with {code}")
    return json.loads((out / "runs.jsonl").read_text().splitlines()[-1])


def measure_sweep(users: int = USERS) -> dict[str, float]:
    """``sweep_sps_1``, ``sweep_sps_2`` (sessions/s), ``sweep_scaling`` (their ratio),
    ``sweep_session_s`` (s per session, 1 worker) and, where Ray is installed, ``sweep_ray_sps_2``
    and ``sweep_ray_overhead`` (Ray's extra wall time per session over the process backend's, as
    a share of a session's time, both with 2 workers)."""
    import importlib.util

    figures: dict[str, float] = {}
    with tempfile.TemporaryDirectory() as tmp:
        spec = Path(tmp) / "bench.yaml"
        spec.write_text(f"grid: {{policy: [ac, lc-noap, lc]}}\nusers: {{synthetic: {users}}}\n")
        one = _run(spec, Path(tmp) / "p1", "--backend", "processes", "--workers", "1")
        two = _run(spec, Path(tmp) / "p2", "--backend", "processes", "--workers", "2")
        figures["sweep_sps_1"] = one["sessions_per_s"]
        figures["sweep_sps_2"] = two["sessions_per_s"]
        figures["sweep_scaling"] = two["sessions_per_s"] / one["sessions_per_s"]
        figures["sweep_session_s"] = one["wall_s"] / one["sessions"]
        if importlib.util.find_spec("ray") is not None:
            ray = _run(spec, Path(tmp) / "r2", "--backend", "ray", "--workers", "2")
            figures["sweep_ray_sps_2"] = ray["sessions_per_s"]
            per_session = 2 * two["wall_s"] / two["sessions"]  # a session's time on a worker
            extra = (ray["wall_s"] - two["wall_s"]) / ray["sessions"] * 2
            figures["sweep_ray_overhead"] = extra / per_session
    return figures
