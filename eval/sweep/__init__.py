"""Sweeps: a grid or random sample of sessions declared in a YAML file, run resumably on local
processes or Ray, one Parquet row per session (``langctrl sweep SWEEP.yaml --out DIR``).

Importing this package imports no optional dependency (neither Ray nor pyarrow).
"""

from __future__ import annotations

from eval.sweep.backend import SWEEP_BACKENDS, Backend, make_backend
from eval.sweep.errors import SweepError
from eval.sweep.grid import SweepSession, expand, session_id
from eval.sweep.spec import SweepSpec, load_spec

__all__ = [
    "SWEEP_BACKENDS",
    "Backend",
    "SweepError",
    "SweepSession",
    "SweepSpec",
    "expand",
    "load_spec",
    "make_backend",
    "session_id",
]
