"""A sweep's summary: per coordinate, per value and policy, the median and bootstrap interval of
every metric; a table and one figure per coordinate.

Writes ``DIR/summary.csv`` (long form: ``coordinate, value, policy, metric, n, median, ci_lo,
ci_hi``), ``DIR/summary.md`` (the main metrics, ``median [ci_lo, ci_hi]``) and
``DIR/plots/COORDINATE.png`` (each main metric's median and interval against the coordinate's
values, one line per policy) for each coordinate with more than one value. Only sessions with
``status == "ok"`` count; the intervals are percentile-bootstrap 95 % intervals of the median
(:func:`eval.stats.bootstrap_ci`, :data:`N_BOOT` resamples, a fixed seed: the same rows give the
same summary).
"""

from __future__ import annotations

import csv
import io
import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from eval.atomic import atomic_write
from eval.metrics import METRICS, NUMERIC_METRICS
from eval.stats import bootstrap_ci

__all__ = ["MAIN_METRICS", "coordinate_rows", "write_summary"]

#: Metrics of the markdown table and the figures.
MAIN_METRICS = ("abs_am", "em_mean_abs", "a_within_0_1", "content_share", "coop_mean")
#: Bootstrap resamples per interval.
N_BOOT = 1000
_FIELDS = ("coordinate", "value", "policy", "metric", "n", "median", "ci_lo", "ci_hi")


def _varying(rows: Sequence[dict[str, Any]], coordinates: Sequence[str]) -> list[str]:
    return [c for c in coordinates if len({r[c] for r in rows if r[c] is not None}) > 1]


def _order(values: set[Any]) -> list[Any]:
    try:
        return sorted(values)
    except TypeError:
        return sorted(values, key=str)


def coordinate_rows(
    rows: Sequence[dict[str, Any]], coordinates: Sequence[str], seed: int = 0
) -> list[dict[str, Any]]:
    """The summary's long table: for each varying coordinate, value, policy and metric."""
    ok = [r for r in rows if r["status"] == "ok"]
    out = []
    for coord in _varying(ok, coordinates):
        groups: dict[tuple[Any, Any], list[dict[str, Any]]] = {}
        for r in ok:
            if r[coord] is not None:
                policy = r[coord] if coord == "policy" else r["policy"]
                groups.setdefault((r[coord], policy), []).append(r)
        for value in _order({v for v, _ in groups}):
            for policy in _order({p for v, p in groups if v == value}):
                group = groups[(value, policy)]
                for metric in NUMERIC_METRICS:
                    x = np.array([float(r[metric]) for r in group])
                    rng = np.random.default_rng(seed)
                    ci = bootstrap_ci(x[~np.isinf(x)], n_boot=N_BOOT, rng=rng)
                    out.append(
                        {
                            "coordinate": coord,
                            "value": value,
                            "policy": policy,
                            "metric": metric,
                            "n": int(np.isfinite(x).sum()),
                            "median": ci.estimate,
                            "ci_lo": ci.lo,
                            "ci_hi": ci.hi,
                        }
                    )
    return out


def write_summary(
    rows: Sequence[dict[str, Any]], coordinates: Sequence[str], out: Path
) -> list[Path]:
    """Write ``summary.csv``, ``summary.md`` and ``plots/*.png`` into ``out``; their paths."""
    table = coordinate_rows(rows, coordinates)
    buf = io.StringIO()
    writer = csv.DictWriter(buf, fieldnames=_FIELDS, lineterminator="\n")
    writer.writeheader()
    writer.writerows(table)
    written = [atomic_write(out / "summary.csv", buf.getvalue())]
    written.append(atomic_write(out / "summary.md", _markdown(rows, table)))
    coords = list(dict.fromkeys(r["coordinate"] for r in table))
    if coords:
        (out / "plots").mkdir(exist_ok=True)
    for coord in coords:
        written.append(_figure([r for r in table if r["coordinate"] == coord], coord, out))
    return written


def _fmt(r: dict[str, Any]) -> str:
    spec = METRICS.get(r["metric"])
    scale = 100.0 if spec is not None and spec.unit == "%" else 1.0
    d = spec.decimals if spec is not None else 3
    if math.isnan(r["median"]):
        return "–"
    return f"{r['median'] * scale:.{d}f} [{r['ci_lo'] * scale:.{d}f}, {r['ci_hi'] * scale:.{d}f}]"


def _markdown(rows: Sequence[dict[str, Any]], table: Sequence[dict[str, Any]]) -> str:
    failed = sum(r["status"] != "ok" for r in rows)
    lines = [
        "# Sweep summary",
        "",
        f"{len(rows)} sessions, {len(rows) - failed} ok, {failed} failed. Each cell: median "
        "[95 % bootstrap interval of the median] over the sessions with that value (all other "
        "coordinates pooled).",
    ]
    for coord in dict.fromkeys(r["coordinate"] for r in table):
        sub = [r for r in table if r["coordinate"] == coord]
        labels = [METRICS[m].label if m in METRICS else m for m in MAIN_METRICS]
        lines += ["", f"## {coord}", "", "| value | policy | n | " + " | ".join(labels) + " |"]
        lines.append("|---" * (3 + len(MAIN_METRICS)) + "|")
        keys = list(dict.fromkeys((r["value"], r["policy"]) for r in sub))
        for value, policy in keys:
            cells = {r["metric"]: r for r in sub if (r["value"], r["policy"]) == (value, policy)}
            n = cells[MAIN_METRICS[0]]["n"]
            body = " | ".join(_fmt(cells[m]) for m in MAIN_METRICS)
            lines.append(f"| {value} | {policy} | {n} | {body} |")
    return "\n".join(lines) + "\n"


def _figure(table: Sequence[dict[str, Any]], coord: str, out: Path) -> Path:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, len(MAIN_METRICS), figsize=(4 * len(MAIN_METRICS), 3.2))
    values = list(dict.fromkeys(r["value"] for r in table))
    numeric = all(isinstance(v, int | float) for v in values)
    for ax, metric in zip(axes, MAIN_METRICS, strict=True):
        sub = [r for r in table if r["metric"] == metric]
        for policy in dict.fromkeys(r["policy"] for r in sub):
            pts = [r for r in sub if r["policy"] == policy]
            x = [r["value"] if numeric else values.index(r["value"]) for r in pts]
            y = np.array([r["median"] for r in pts])
            err = np.array(
                [[r["median"] - r["ci_lo"] for r in pts], [r["ci_hi"] - r["median"] for r in pts]]
            )
            ax.errorbar(x, y, yerr=err, marker="o", capsize=3, label=str(policy))
        if not numeric:
            ax.set_xticks(range(len(values)), [str(v) for v in values], rotation=30, ha="right")
        spec = METRICS.get(metric)
        ax.set_title(spec.label if spec else metric)
        ax.set_xlabel(coord)
    axes[0].legend(fontsize=7)
    fig.tight_layout()
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=90)
    plt.close(fig)
    return atomic_write(out / "plots" / f"{coord}.png", buf.getvalue())
