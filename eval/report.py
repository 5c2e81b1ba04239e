"""Tables of an evaluation: ``sessions.csv`` (one row per episode) and ``summary.md``.

``summary.md`` is meant for a paper's supplement: per policy the median and interquartile range of
every metric, percentile-bootstrap 95 % intervals for the differences against the reference policy
(LC; paired by user when both ran the same users), and the study's findings checked on the data,
each with its measured value and PASS/FAIL. Every file is written atomically (to a temporary file
in the same directory, then renamed), so an error never leaves a partial file behind.

Regenerate a summary from a saved table with ``langctrl report DIR/sessions.csv``.
"""

from __future__ import annotations

import csv
import io
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from eval.atomic import atomic_write
from eval.metrics import A_TOLERANCE, METRIC_COLUMNS, METRICS, NUMERIC_METRICS, OPTIONAL_METRICS
from eval.stats import MetricSummary, Stat, SummaryTable, median_iqr, summarise
from langenv.errors import ConfigError, SessionDataError

__all__ = [
    "AM_TOLERANCE",
    "MIXED_MARK",
    "Finding",
    "atomic_write",
    "display_name",
    "graphs_spoken",
    "mixed_graph_policies",
    "read_sessions_csv",
    "render_summary_md",
    "study_findings",
    "write_sessions_csv",
    "write_summary_md",
]

AM_TOLERANCE = 1.0
"""The study's bound on LC's |AM| (s)."""

_NAMES = {
    "ac": "AC",
    "lc-noap": "LC-noAP",
    "lc": "LC",
    "lc-em": "LC-EM",
    "lc-end": "LC-end",
    "lc-em-end": "LC-EM-end",
    "ppo": "PPO",
}

Row = Mapping[str, object]


def display_name(policy: str) -> str:
    """The paper's name of a policy (``"lc-noap"`` -> ``"LC-noAP"``); others unchanged."""
    return _NAMES.get(policy, policy)


MIXED_MARK = "\u2020"
"""Marks, in tables, the policies of one graph role that spoke different phrase graphs."""

_ROLE_WORDS = {"single": "one wording", "graph": "chooses phrases"}


def graphs_spoken(rows: Sequence[Row], policies: Sequence[str]) -> dict[str, str]:
    """Per policy the phrase graph(s) it spoke, as the rows' ``graph`` column names them
    (several joined with ``", "``); empty when the rows have no such column (older tables)."""
    if not any(r.get("graph") for r in rows):
        return {}
    out = {}
    for p in policies:
        found = dict.fromkeys(str(r.get("graph") or "") for r in rows if str(r["policy"]) == p)
        out[p] = ", ".join(g for g in found if g) or "n/a"
    return out


def mixed_graph_policies(rows: Sequence[Row], policies: Sequence[str]) -> list[str]:
    """The policies of a graph role (``graph_role`` column) whose policies spoke different
    phrase graphs: a table of them compares scripts as well as controllers. AC and LC-noAP
    saying one wording while LC chooses among many is one role each, so not mixed."""
    spoken = graphs_spoken(rows, policies)
    roles: dict[str, dict[str, str]] = {}
    for p, graph in spoken.items():
        role = next((str(r.get("graph_role") or "") for r in rows if str(r["policy"]) == p), "")
        roles.setdefault(role, {})[p] = graph
    return [p for p in policies if any(p in g and len(set(g.values())) > 1 for g in roles.values())]


def _graphs_line(rows: Sequence[Row], policies: Sequence[str], mixed: Sequence[str]) -> list[str]:
    """The phrase graphs spoken, and a note when policies of one role spoke different ones."""
    spoken = graphs_spoken(rows, policies)
    if not spoken:
        return []
    parts = []
    for p, graph in spoken.items():
        role = next((str(r.get("graph_role") or "") for r in rows if str(r["policy"]) == p), "")
        words = f" ({_ROLE_WORDS[role]})" if role in _ROLE_WORDS else ""
        parts.append(f"{_marked(p, mixed)} `{graph}`{words}")
    lines = [f"Phrase graphs spoken: {'; '.join(parts)}.", ""]
    if mixed:
        names = ", ".join(display_name(p) for p in mixed)
        lines += [
            f"{MIXED_MARK} **Mixed graphs**: {names} spoke different phrase graphs in one role "
            "(run with `--allow-mixed-graphs`), so differences between them compare scripts as "
            "well as controllers.",
            "",
        ]
    return lines


def _marked(policy: str, mixed: Sequence[str]) -> str:
    """The policy's display name, marked when it spoke a graph others of its role did not."""
    return display_name(policy) + (f" {MIXED_MARK}" if policy in mixed else "")


def _columns(rows: Sequence[Row]) -> list[str]:
    """:data:`METRIC_COLUMNS` first, then any further keys in order of first appearance."""
    if not rows:
        raise ConfigError("rows must not be empty")
    extra: list[str] = []
    for i, row in enumerate(rows):
        missing = [c for c in METRIC_COLUMNS if c not in row and c not in OPTIONAL_METRICS]
        if missing:
            raise ConfigError(f"rows[{i}] lacks column(s) {', '.join(missing)}")
        extra.extend(k for k in row if k not in METRIC_COLUMNS and k not in extra)
    return [*METRIC_COLUMNS, *extra]


def write_sessions_csv(rows: Sequence[Row], path: str | Path) -> Path:
    """Write one row per episode: :data:`~eval.metrics.METRIC_COLUMNS`, then any extra keys.

    Floats are written with full precision (``repr``), NaN as ``nan``.

    Args:
        rows: Session rows, e.g. from :func:`eval.metrics.episode_metrics`.
        path: Destination CSV.

    Returns:
        The path written.

    Raises:
        ConfigError: if ``rows`` is empty or a row lacks a column.
    """
    columns = _columns(rows)
    buf = io.StringIO()
    writer = csv.DictWriter(buf, fieldnames=columns, lineterminator="\n", restval="")
    writer.writeheader()
    for row in rows:
        writer.writerow({k: row.get(k, "") for k in columns})
    return atomic_write(path, buf.getvalue())


def read_sessions_csv(path: str | Path) -> list[dict[str, float | str]]:
    """Read a table written by :func:`write_sessions_csv`.

    ``policy`` and ``user`` stay str; every column of :data:`~eval.metrics.NUMERIC_METRICS` is
    parsed as float (empty or ``nan`` -> NaN); other columns are parsed as float when they all
    are numbers, else kept as str.

    Raises:
        SessionDataError: naming the file, if it is unreadable, lacks a column or holds a
            non-number in a metric column.
    """
    path = Path(path)
    try:
        with path.open(newline="", encoding="utf-8") as fh:
            raw = list(csv.DictReader(fh))
            header = list(raw[0]) if raw else []
    except (OSError, UnicodeDecodeError, csv.Error) as exc:
        raise SessionDataError(f"{path}: cannot read sessions table: {exc}") from None
    if not raw:
        raise SessionDataError(f"{path}: no session rows")
    missing = [c for c in METRIC_COLUMNS if c not in header and c not in OPTIONAL_METRICS]
    if missing:
        raise SessionDataError(f"{path}: lacks column(s) {', '.join(missing)}")

    def number(text: str | None) -> float:
        return float("nan") if text is None or text.strip() == "" else float(text)

    numeric = set(NUMERIC_METRICS)
    for c in header:
        if c in numeric or c in ("policy", "user"):
            continue
        try:
            for r in raw:
                number(r[c])
            numeric.add(c)
        except ValueError:
            pass
    rows: list[dict[str, float | str]] = []
    for line, r in enumerate(raw, start=2):
        row: dict[str, float | str] = {}
        for c in header:
            if c in numeric:
                try:
                    row[c] = number(r[c])
                except ValueError:
                    raise SessionDataError(
                        f"{path}, line {line}: column {c!r} is not a number: {r[c]!r}"
                    ) from None
            else:
                row[c] = r[c] or ""
        for c in OPTIONAL_METRICS - set(header):  # a table of an older run
            row[c] = float("nan")
        rows.append(row)
    return rows


@dataclass(frozen=True)
class Finding:
    """A claim of the study checked on the data.

    Attributes:
        claim: The claim, in words.
        measured: What was measured, with numbers and units.
        passed: True/False, or ``None`` when it cannot be checked (a policy did not run).
    """

    claim: str
    measured: str
    passed: bool | None

    @property
    def verdict(self) -> str:
        """``"PASS"``, ``"FAIL"`` or ``"n/a"``."""
        return "n/a" if self.passed is None else ("PASS" if self.passed else "FAIL")


def _column(rows: Sequence[Row], policy: str, metric: str) -> np.ndarray:
    return np.array(
        [float(r[metric]) for r in rows if r["policy"] == policy],  # type: ignore[arg-type]
        dtype=np.float64,
    )


def study_findings(
    rows: Sequence[Row], ac: str = "ac", lc_noap: str = "lc-noap", lc: str = "lc"
) -> list[Finding]:
    """The study's three findings, measured on session rows.

    1. Median |AM| orders AC > LC-noAP > LC.
    2. LC's |AM| is at most :data:`AM_TOLERANCE` (1 s) in every session.
    3. LC speaks within 0.1 of the natural audio pace for a larger share of its speech time than
       LC-noAP (shares pooled over sessions, each weighted by its speech duration ``t_speech``).

    Args:
        rows: Session rows with ``policy``, ``abs_am``, ``a_within_0_1`` and ``t_speech``.
        ac: Name of the AC policy in the rows.
        lc_noap: Name of the LC-noAP policy.
        lc: Name of the LC policy.

    Returns:
        The three :class:`Finding`, in order.
    """
    present = {str(r["policy"]) for r in rows}
    n_ac, n_noap, n_lc = display_name(ac), display_name(lc_noap), display_name(lc)
    out: list[Finding] = []

    claim = f"median |AM| orders {n_ac} > {n_noap} > {n_lc}"
    if {ac, lc_noap, lc} <= present:
        med = [median_iqr(_column(rows, p, "abs_am")).median for p in (ac, lc_noap, lc)]
        measured = f"{n_ac} {med[0]:.2f} s, {n_noap} {med[1]:.2f} s, {n_lc} {med[2]:.2f} s"
        out.append(Finding(claim, measured, bool(med[0] > med[1] > med[2])))
    else:
        out.append(Finding(claim, _absent({ac, lc_noap, lc} - present), None))

    claim = f"{n_lc}'s |AM| <= {AM_TOLERANCE:g} s in every session"
    if lc in present:
        am = _column(rows, lc, "abs_am")
        ok = int((am <= AM_TOLERANCE).sum())
        measured = f"max {np.nanmax(am):.2f} s; {ok}/{am.size} sessions within {AM_TOLERANCE:g} s"
        out.append(Finding(claim, measured, ok == am.size))
    else:
        out.append(Finding(claim, _absent({lc}), None))

    claim = (
        f"{n_lc} keeps |a - 1| <= {A_TOLERANCE:g} for a larger share of all speech time (pooled) "
        f"than {n_noap}"
    )
    if {lc_noap, lc} <= present:
        shares = []
        for p in (lc, lc_noap):
            share, weight = _column(rows, p, "a_within_0_1"), _column(rows, p, "t_speech")
            keep = np.isfinite(share) & (weight > 0.0)
            total = float(weight[keep].sum())
            kept = np.sum(share[keep] * weight[keep])  # not BLAS's dot: the same on any CPU
            shares.append(float(kept / total) if total else math.nan)
        measured = f"{n_lc} {100 * shares[0]:.1f} % vs {n_noap} {100 * shares[1]:.1f} %"
        out.append(Finding(claim, measured, bool(shares[0] > shares[1])))
    else:
        out.append(Finding(claim, _absent({lc_noap, lc} - present), None))
    return out


def _absent(policies: set[str]) -> str:
    names = ", ".join(sorted(display_name(p) for p in policies))
    return f"not checked: no sessions of {names}"


def _fmt(value: float, metric: str, signed: bool = False) -> str:
    spec = METRICS[metric]
    if not math.isfinite(value):
        return "n/a"
    if spec.unit == "%":
        value *= 100.0
    value = round(value, spec.decimals) + 0.0  # + 0.0: no "-0.00" in tables
    return f"{value:+.{spec.decimals}f}" if signed else f"{value:.{spec.decimals}f}"


def _label(metric: str) -> str:
    spec = METRICS[metric]
    return f"{spec.label} ({spec.unit})" if spec.unit else spec.label


def _spread_cell(cell: MetricSummary) -> str:
    s = cell.spread
    if s.n == 0:
        return "n/a"
    return f"{_fmt(s.median, cell.metric)} [{_fmt(s.q1, cell.metric)}, {_fmt(s.q3, cell.metric)}]"


def _diff_cell(cell: MetricSummary) -> str:
    d = cell.diff
    if d is None or not math.isfinite(d.estimate):
        return "n/a"
    mark = " *" if d.excludes_zero else ""
    m = cell.metric
    return f"{_fmt(d.estimate, m, True)} [{_fmt(d.lo, m, True)}, {_fmt(d.hi, m, True)}]{mark}"


def _cell(text: str) -> str:
    """Escape a table cell: a bare ``|`` would end the cell."""
    return text.replace("|", "\\|")


def _stops_line(rows: Sequence[Row], policies: Sequence[str]) -> str:
    """``Protective stops: ...`` per policy, with the limits; "" when the table has no column."""
    if not any("protective_stop" in r for r in rows):
        return ""
    parts = []
    for p in policies:
        mine = [r for r in rows if str(r["policy"]) == p]
        stopped = [r for r in mine if float(r.get("protective_stop") or 0.0) > 0.0]  # type: ignore[arg-type]
        limits = sorted(
            {str(r.get("stop_limit")) for r in stopped if isinstance(r.get("stop_limit"), str)}
            - {""}
        )
        counts = [f"{lim} {sum(r.get('stop_limit') == lim for r in stopped)}" for lim in limits]
        detail = f" ({', '.join(counts)})" if counts else ""
        parts.append(f"{display_name(p)} {len(stopped)} of {len(mine)}{detail}")
    return (
        "Protective stops (the arm halted at a safety limit; the session's metrics cover it up "
        f"to the stop): {'; '.join(parts)}."
    )


def _table(header: Sequence[str], body: Sequence[Sequence[str]]) -> list[str]:
    lines = [
        "| " + " | ".join(_cell(h) for h in header) + " |",
        "|" + "|".join([":---"] * len(header)) + "|",
    ]
    lines.extend("| " + " | ".join(_cell(c) for c in r) + " |" for r in body)
    return lines


def render_summary_md(
    rows: Sequence[Row],
    reference: str = "lc",
    *,
    rng: np.random.Generator,
    policies: Sequence[str] | None = None,
    metrics: Sequence[str] = NUMERIC_METRICS,
    stat: Stat = "median",
    n_boot: int = 10_000,
    level: float = 0.95,
    figure: str | None = None,
) -> str:
    """The text of ``summary.md`` (see :func:`write_summary_md`)."""
    table: SummaryTable = summarise(
        rows, metrics, reference, rng=rng, policies=policies, stat=stat, n_boot=n_boot, level=level
    )
    users = sorted({str(r["user"]) for r in rows if str(r["policy"]) in table.policies})
    mixed = mixed_graph_policies(rows, table.policies)
    ref_name = display_name(reference)
    pct = f"{100 * level:g} %"
    boot = f"{n_boot:,}".replace(",", " ")
    counts = ", ".join(f"{display_name(p)} {table.n_sessions[p]}" for p in table.policies)
    has_ref = any(str(r["policy"]) == reference for r in rows)
    against = (
        f"Differences are taken against **{ref_name}** with percentile-bootstrap {pct} "
        f"intervals ({boot} resamples per interval)."
        if has_ref
        else f"No sessions of the reference {ref_name}, so no differences."
    )
    lines = [
        "# LangCtrl evaluation summary",
        "",
        f"{sum(table.n_sessions.values())} sessions ({counts}) with {len(users)} distinct users. "
        + against,
        "",
    ]
    lines += _graphs_line(rows, table.policies, mixed)
    stops = _stops_line(rows, table.policies)
    if stops:
        lines += [stops, ""]
    if figure:
        lines += [f"![Distributions per controller]({figure})", ""]

    lines += _md_findings(rows)
    lines += _md_spread(table, metrics, mixed)
    lines += _md_differences(
        table, metrics, reference, stat=stat, pct=pct, has_ref=has_ref, mixed=mixed
    )
    lines += _md_how_to_read(ref_name, pct)
    return "\n".join(lines)


def _md_findings(rows: Sequence[Row]) -> list[str]:
    """The study's findings, recomputed on ``rows``."""
    body = [
        [str(k), f.claim, f.measured, f"**{f.verdict}**"]
        for k, f in enumerate(study_findings(rows), start=1)
    ]
    return [
        "## Findings of the study, checked on these sessions",
        "",
        *_table(["#", "finding (paper)", "measured here", "result"], body),
        "",
    ]


def _md_spread(table: SummaryTable, metrics: Sequence[str], mixed: Sequence[str] = ()) -> list[str]:
    """Per controller: median [Q1, Q3] of every metric."""
    names = [_marked(p, mixed) for p in table.policies]
    header = [
        "metric",
        *(f"{n} (n={table.n_sessions[p]})" for n, p in zip(names, table.policies, strict=True)),
    ]
    body = [[_label(m), *(_spread_cell(table[p, m]) for p in table.policies)] for m in metrics]
    return ["## Per controller: median [Q1, Q3] over sessions", "", *_table(header, body), ""]


def _md_differences(
    table: SummaryTable,
    metrics: Sequence[str],
    reference: str,
    *,
    stat: Stat,
    pct: str,
    has_ref: bool,
    mixed: Sequence[str] = (),
) -> list[str]:
    """Every other controller minus the reference, with its bootstrap interval."""
    ref_name = _marked(reference, mixed)
    others = [p for p in table.policies if p != reference]
    what = "median of per-user differences" if stat == "median" else "mean difference"
    lines = [f"## Differences against {ref_name}: {what} [{pct} CI]", ""]
    if not has_ref:
        lines.append(f"No sessions of the reference {ref_name}: no differences computed.")
    elif not others:
        lines.append(f"No other controller to compare with {ref_name}.")
    else:
        header = ["metric"]
        for p in others:
            kind = "paired by user" if table[p, metrics[0]].paired else "unpaired"
            header.append(f"{_marked(p, mixed)} - {ref_name} ({kind})")
        body = [[_label(m), *(_diff_cell(table[p, m]) for p in others)] for m in metrics]
        lines += _table(header, body)
    return [*lines, ""]


def _md_how_to_read(ref_name: str, pct: str) -> list[str]:
    """The closing paragraph: what the metrics and cells mean."""
    return [
        "## How to read this",
        "",
        "AM (actual misalignment) is the speech end minus the motion end of a session: positive "
        "when the motion finished first, and the closer to 0 the better aligned. EM is the "
        "controller's running estimate t_a - t_x of it; mean |EM| averages it over the time "
        "motion or speech was still going on. Audio pace a and physical pace p are relative to "
        "the natural pace 1 (a is averaged while speaking, p and the cooperation c while moving); "
        f"'|a-1| <= {A_TOLERANCE:g}' is the share of speech time spent near the natural pace. "
        "Per-controller cells give the median and the interquartile range [Q1, Q3] over "
        f"sessions. Difference cells give controller minus {ref_name} with a percentile-bootstrap "
        f"{pct} interval; when both ran the same users the sessions are paired by user and the "
        "cell is the statistic of the per-user differences. An asterisk marks an interval that "
        "excludes 0. n/a: not defined for those sessions (e.g. no speech) or not run. The "
        "findings are recomputed from these sessions on every run, never copied from the paper.",
        "",
    ]


def write_summary_md(
    rows: Sequence[Row],
    path: str | Path,
    reference: str = "lc",
    **options: Any,
) -> Path:
    """Write ``summary.md``: findings, per-controller spreads and differences against a reference.

    Args:
        rows: Session rows (``policy``, ``user`` and the metric columns).
        path: Destination markdown file (written atomically).
        reference: Policy the differences are taken against.
        **options: :func:`render_summary_md`'s keyword arguments (``rng``, required;
            ``policies``, ``metrics``, ``stat``, ``n_boot``, ``level``, ``figure``).

    Returns:
        The path written.

    Raises:
        ConfigError: for empty rows, missing columns or a requested policy without sessions.
    """
    text = render_summary_md(rows, reference, **options)
    return atomic_write(path, text)
