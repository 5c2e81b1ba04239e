"""A sweep's rows on disk: Parquet part files, each written whole or not at all.

``DIR/rows/part-NNNNNN.parquet`` holds the rows of one finished batch, written to a temporary
name, flushed to disk and renamed (:func:`eval.atomic.atomic_write`): a sweep killed at any
moment (the driver, a worker, the machine) leaves whole parts only, and ``--resume`` runs the
sessions that have no row. Read them all with ``pandas.read_parquet("DIR/rows")`` or DuckDB's
``read_parquet('DIR/rows/*.parquet')``.

Every part has the same schema (:func:`row_schema`): the episode's columns (``sessions.csv``),
the coordinates, ``session_id``, ``seed``, ``status``, ``error``, ``version``. A session has one
row: a session run again (``--retry-failed``, ``--only``) gets a newer part, and the older part is
rewritten without its row (:meth:`SweepStore.drop_superseded`); readers keep the newest row of
an id in any case. A part that cannot be read (a disk that lost it) is moved aside to
``DIR/rows/bad/`` and its sessions run again.
"""

from __future__ import annotations

import fcntl
import io
import os
import re
import sys
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from eval.sweep.errors import SweepError
from eval.sweep.spec import COORDINATES, SweepSpec

__all__ = ["SweepStore", "row_schema"]

_PART = re.compile(r"part-(\d{6,})\.parquet")


def row_schema(spec: SweepSpec) -> Any:
    """The Arrow schema of every row of ``spec``'s sweep."""
    import pyarrow as pa

    from eval.compare import EPISODE_COLUMNS, TEXT_COLUMNS

    fields = [(c, pa.string() if c in TEXT_COLUMNS else pa.float64()) for c in EPISODE_COLUMNS]
    coords = [
        ("policy_spec", pa.string()),
        *[(c, pa.int64() if c == "decision_hz" else pa.string()) for c in COORDINATES[1:]],
        *[(n, pa.float64()) for n in spec.param_names],
        ("sample", pa.int64()),
        ("users", pa.string()),
    ]
    tail = [
        ("session_id", pa.string()),
        ("seed", pa.int64()),
        ("status", pa.string()),
        ("error", pa.string()),
        ("version", pa.string()),
    ]
    return pa.schema(fields + coords + tail)


class SweepStore:
    """The ``rows`` directory of a sweep, held by one driver at a time (a lock file).

    Args:
        root: The sweep's output directory.
        schema: :func:`row_schema` of its spec.

    Raises:
        SweepError: another driver holds the directory.
    """

    def __init__(self, root: Path, schema: Any) -> None:
        self.root = root
        self.dir = root / "rows"
        self.dir.mkdir(parents=True, exist_ok=True)
        self.schema = schema
        self._lock = open(root / ".lock", "w")  # held for the store's life
        try:
            # A POSIX record lock: held by this process only, not by the workers it forks.
            fcntl.lockf(self._lock, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            self._lock.close()
            raise SweepError(
                root, "", "another langctrl sweep is running in this directory"
            ) from None
        self._next = max(self._parts(), default=-1) + 1

    def close(self) -> None:
        """Release the directory."""
        self._lock.close()

    def _parts(self) -> dict[int, Path]:
        found = {}
        for p in self.dir.iterdir():
            m = _PART.fullmatch(p.name)
            if m:
                found[int(m.group(1))] = p
        return dict(sorted(found.items()))

    def write_part(self, rows: Sequence[Mapping[str, Any]]) -> Path:
        """Write ``rows`` as the next part (durably, whole or not at all)."""
        import pyarrow as pa
        import pyarrow.parquet as pq

        from eval.atomic import atomic_write

        unknown = {k for r in rows for k in r} - set(self.schema.names)
        if unknown:  # Arrow would drop them without a word
            raise KeyError(f"rows hold columns the sweep's schema lacks: {sorted(unknown)}")
        table = pa.Table.from_pylist([dict(r) for r in rows], schema=self.schema)
        buf = io.BytesIO()
        pq.write_table(table, buf, compression="zstd")
        path = self.dir / f"part-{self._next:06d}.parquet"
        self._next += 1
        return atomic_write(path, buf.getvalue(), durable=True)

    def read(self) -> Any:
        """Every row, the newest of each ``session_id``, as an Arrow table (unreadable parts
        moved aside to ``rows/bad/``)."""
        import pyarrow as pa
        import pyarrow.parquet as pq

        tables = []
        for path in self._parts().values():
            try:
                tables.append(pq.read_table(path, schema=self.schema))
            except (OSError, pa.ArrowInvalid) as exc:
                bad = self.dir / "bad"
                bad.mkdir(exist_ok=True)
                os.replace(path, bad / path.name)
                print(
                    f"langctrl sweep: {path.name} unreadable ({exc}); moved to {bad}",
                    file=sys.stderr,
                )
        if not tables:
            return self.schema.empty_table()
        table = pa.concat_tables(tables)
        ids = table.column("session_id").to_pylist()
        last = {sid: i for i, sid in enumerate(ids)}
        if len(last) == len(ids):
            return table
        return table.take(sorted(last.values()))

    def statuses(self) -> dict[str, str]:
        """``session_id -> status`` of every session with a row."""
        table = self.read()
        ids = table.column("session_id").to_pylist()
        return dict(zip(ids, table.column("status").to_pylist(), strict=True))

    def drop_superseded(self) -> int:
        """Rewrite each part without the rows a newer part holds again; returns rows dropped."""
        import pyarrow as pa
        import pyarrow.compute as pc
        import pyarrow.parquet as pq

        from eval.atomic import atomic_write

        parts = list(self._parts().items())
        newer: set[str] = set()
        dropped = 0
        for _, path in reversed(parts):
            table = pq.read_table(path, schema=self.schema)
            ids = table.column("session_id")
            stale = pc.is_in(ids, value_set=pa.array(sorted(newer), pa.string()))
            n_stale = pc.sum(stale).as_py() or 0
            if n_stale:
                kept = table.filter(pc.invert(stale))
                if kept.num_rows == 0:
                    path.unlink()
                else:
                    buf = io.BytesIO()
                    pq.write_table(kept, buf, compression="zstd")
                    atomic_write(path, buf.getvalue(), durable=True)
                dropped += n_stale
            newer.update(ids.to_pylist())
        return dropped
