"""Robust summaries and bootstrap intervals for comparing policies over sessions.

* :func:`median_iqr`: median and quartiles of one metric under one policy.
* :func:`bootstrap_diff_ci`: percentile-bootstrap interval for the difference of a statistic
  between two policies, paired (by user) or not; vectorised over resamples.
* :func:`summarise`: both, for every policy and metric of a list of session rows, with differences
  taken against a reference policy (LC).

Missing values (NaN, e.g. an audio metric of a session without speech) are left out and counted;
infinite values are an error.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Literal, NamedTuple

import numpy as np

from eval.metrics import OPTIONAL_METRICS
from langenv.errors import ConfigError

__all__ = [
    "DiffCI",
    "MedianIQR",
    "MetricSummary",
    "Stat",
    "SummaryTable",
    "bootstrap_ci",
    "bootstrap_diff_ci",
    "median_iqr",
    "summarise",
]

Stat = Literal["mean", "median"]

_CHUNK_ELEMENTS = 4_000_000  # bootstrap resamples are drawn in chunks of at most this many values


@dataclass(frozen=True)
class MedianIQR:
    """Median and quartiles of a sample.

    Attributes:
        median: The median (NaN when ``n == 0``).
        q1: First quartile (25th percentile, linear interpolation).
        q3: Third quartile (75th percentile).
        n: Number of finite values it was computed from.
    """

    median: float
    q1: float
    q3: float
    n: int

    @property
    def iqr(self) -> float:
        """Interquartile range ``q3 - q1``."""
        return self.q3 - self.q1


class DiffCI(NamedTuple):
    """A difference of statistics with its bootstrap interval (unpacks as a 3-tuple)."""

    estimate: float
    lo: float
    hi: float

    @property
    def excludes_zero(self) -> bool:
        """Whether the interval lies strictly on one side of zero."""
        return self.lo > 0.0 or self.hi < 0.0


def _as_1d(x: Sequence[float] | np.ndarray, name: str) -> np.ndarray:
    try:
        arr = np.asarray(x, dtype=np.float64)
    except (TypeError, ValueError):
        raise ConfigError(f"{name} must be numeric") from None
    if arr.ndim != 1:
        raise ConfigError(f"{name} must have shape (n,), got {arr.shape}")
    if np.isinf(arr).any():
        raise ConfigError(f"{name} must not contain infinite values")
    return arr


def median_iqr(x: Sequence[float] | np.ndarray) -> MedianIQR:
    """Median and quartiles of the finite values of ``x``.

    Args:
        x: Values, shape ``(n,)``; NaNs are ignored.

    Returns:
        The :class:`MedianIQR`; all NaN with ``n = 0`` when there is no finite value.

    Raises:
        ConfigError: if ``x`` is not 1-D numeric or holds infinite values.
    """
    arr = _as_1d(x, "x")
    arr = arr[~np.isnan(arr)]
    if arr.size == 0:
        nan = float("nan")
        return MedianIQR(nan, nan, nan, 0)
    q1, med, q3 = np.percentile(arr, [25.0, 50.0, 75.0])
    return MedianIQR(float(med), float(q1), float(q3), int(arr.size))


def _stat_rows(samples: np.ndarray, stat: Stat) -> np.ndarray:
    """The statistic of each row of ``samples`` (shape (b, n)) -> shape (b,)."""
    if stat == "mean":
        return samples.mean(axis=1)
    return np.median(samples, axis=1)


def _boot(x: np.ndarray, stat: Stat, n_boot: int, rng: np.random.Generator) -> np.ndarray:
    """``n_boot`` bootstrap replicates of ``stat`` of ``x``, shape ``(n_boot,)``."""
    n = x.shape[0]
    out = np.empty(n_boot)
    chunk = max(1, _CHUNK_ELEMENTS // n)
    for start in range(0, n_boot, chunk):
        stop = min(n_boot, start + chunk)
        idx = rng.integers(0, n, size=(stop - start, n))
        out[start:stop] = _stat_rows(x[idx], stat)
    return out


def bootstrap_diff_ci(
    x: Sequence[float] | np.ndarray,
    y: Sequence[float] | np.ndarray,
    *,
    paired: bool,
    stat: Stat = "mean",
    n_boot: int = 10_000,
    rng: np.random.Generator,
    level: float = 0.95,
) -> DiffCI:
    """Percentile-bootstrap interval for a difference between two samples.

    Paired (``x[i]``, ``y[i]`` from the same user): the estimate is ``stat(x - y)`` and pairs are
    resampled together. Unpaired: the estimate is ``stat(x) - stat(y)`` and each sample is
    resampled on its own. The interval is the ``(1 - level) / 2`` and ``(1 + level) / 2``
    percentiles of the bootstrap replicates.

    Args:
        x: First sample, shape ``(n,)`` (e.g. a policy's per-session values).
        y: Second sample (e.g. the reference policy's); same length and order when paired.
        paired: Whether ``x`` and ``y`` are paired element by element.
        stat: ``"mean"`` or ``"median"``.
        n_boot: Number of bootstrap resamples, >= 100.
        rng: Source of randomness.
        level: Confidence level in (0, 1).

    Returns:
        ``DiffCI(estimate, lo, hi)``. NaNs are dropped first (a pair is dropped when either value
        is NaN); with nothing left on either side all three are NaN.

    Raises:
        ConfigError: naming the argument, for infinite values, paired samples of unequal length,
            an unknown ``stat``, ``n_boot < 100``, ``level`` outside (0, 1) or a non-Generator rng.
    """
    xa, ya = _as_1d(x, "x"), _as_1d(y, "y")
    _check_boot_args(stat, n_boot, level)
    if not isinstance(rng, np.random.Generator):
        raise ConfigError(f"rng must be a numpy.random.Generator, got {type(rng).__name__}")
    nan = float("nan")
    tails = [50.0 * (1.0 - level), 50.0 * (1.0 + level)]
    if paired:
        if xa.shape != ya.shape:
            raise ConfigError(
                f"paired samples need equal lengths, got x: {xa.shape[0]}, y: {ya.shape[0]}"
            )
        keep = ~(np.isnan(xa) | np.isnan(ya))
        d = xa[keep] - ya[keep]
        if d.size == 0:
            return DiffCI(nan, nan, nan)
        estimate = float(_stat_rows(d[None, :], stat)[0])
        reps = _boot(d, stat, n_boot, rng)
    else:
        xa, ya = xa[~np.isnan(xa)], ya[~np.isnan(ya)]
        if xa.size == 0 or ya.size == 0:
            return DiffCI(nan, nan, nan)
        estimate = float(_stat_rows(xa[None, :], stat)[0] - _stat_rows(ya[None, :], stat)[0])
        reps = _boot(xa, stat, n_boot, rng) - _boot(ya, stat, n_boot, rng)
    lo, hi = np.percentile(reps, tails)
    return DiffCI(estimate, float(lo), float(hi))


def bootstrap_ci(
    x: Sequence[float] | np.ndarray,
    *,
    stat: Stat = "median",
    n_boot: int = 2_000,
    rng: np.random.Generator,
    level: float = 0.95,
) -> DiffCI:
    """Percentile-bootstrap interval for a statistic of one sample.

    Args:
        x: The sample, shape ``(n,)``; NaNs are dropped first.
        stat: ``"mean"`` or ``"median"``.
        n_boot: Number of bootstrap resamples, >= 100.
        rng: Source of randomness.
        level: Confidence level in (0, 1).

    Returns:
        ``DiffCI(estimate, lo, hi)``; all NaN for an empty sample.

    Raises:
        ConfigError: as :func:`bootstrap_diff_ci`.
    """
    xa = _as_1d(x, "x")
    _check_boot_args(stat, n_boot, level)
    xa = xa[~np.isnan(xa)]
    if xa.size == 0:
        nan = float("nan")
        return DiffCI(nan, nan, nan)
    estimate = float(_stat_rows(xa[None, :], stat)[0])
    lo, hi = np.percentile(_boot(xa, stat, n_boot, rng), [50.0 * (1 - level), 50.0 * (1 + level)])
    return DiffCI(estimate, float(lo), float(hi))


@dataclass(frozen=True)
class MetricSummary:
    """One metric under one policy, and its difference against the reference policy.

    Attributes:
        policy: Policy name.
        metric: Metric (column) name.
        spread: Median and quartiles over this policy's sessions.
        diff: ``policy - reference`` with its bootstrap interval; ``None`` for the reference
            itself or when the reference did not run.
        paired: Whether ``diff`` was computed on user-paired sessions.
    """

    policy: str
    metric: str
    spread: MedianIQR
    diff: DiffCI | None
    paired: bool


@dataclass(frozen=True)
class SummaryTable:
    """:func:`summarise`'s result: a :class:`MetricSummary` per (policy, metric).

    Attributes:
        policies: Policies in the order given (the order of first appearance by default).
        metrics: Metrics in the order given.
        reference: The reference policy of the differences.
        stat: Statistic of the differences (``"median"`` or ``"mean"``).
        level: Confidence level of the intervals.
        n_boot: Bootstrap resamples per interval.
        n_sessions: Sessions per policy.
        cells: ``(policy, metric) -> MetricSummary``.
    """

    policies: tuple[str, ...]
    metrics: tuple[str, ...]
    reference: str
    stat: Stat
    level: float
    n_boot: int
    n_sessions: Mapping[str, int]
    cells: Mapping[tuple[str, str], MetricSummary]

    def __getitem__(self, key: tuple[str, str]) -> MetricSummary:
        return self.cells[key]


def _value(row: Mapping[str, object], metric: str, index: int) -> float:
    if metric not in row:
        if metric in OPTIONAL_METRICS:
            return float("nan")  # a table of an older run
        raise ConfigError(f"rows[{index}] lacks metric {metric!r}")
    value = row[metric]
    try:
        return float(value)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        raise ConfigError(f"rows[{index}][{metric!r}] is not a number: {value!r}") from None


def _pairing(users_x: list[str], users_y: list[str]) -> tuple[list[int], list[int]] | None:
    """Index orders that pair x with y by user, or None when the sessions do not pair up.

    Sessions pair up when both policies ran exactly the same users, each once.
    """
    cx, cy = Counter(users_x), Counter(users_y)
    if cx != cy or any(c != 1 for c in cx.values()):
        return None
    order_y = {u: i for i, u in enumerate(users_y)}
    return list(range(len(users_x))), [order_y[u] for u in users_x]


def summarise(
    rows: Sequence[Mapping[str, object]],
    metrics: Sequence[str],
    reference: str = "lc",
    *,
    rng: np.random.Generator,
    policies: Sequence[str] | None = None,
    stat: Stat = "median",
    n_boot: int = 10_000,
    level: float = 0.95,
) -> SummaryTable:
    """Median/IQR per policy and metric, and bootstrap differences against ``reference``.

    Differences are ``policy - reference``. They are paired by user when both policies ran exactly
    the same users once each (then the statistic is that of the per-user differences), unpaired
    otherwise (the difference of the statistics).

    Args:
        rows: Session rows with ``policy``, ``user`` and the metric columns (e.g. from
            :func:`eval.metrics.episode_metrics` or a read ``sessions.csv``).
        metrics: Metric columns to summarise.
        reference: Policy the others are compared against; if it did not run, no differences.
        rng: Source of randomness for the bootstrap.
        policies: Order (and selection) of policies; default: order of first appearance.
        stat: Statistic of the differences.
        n_boot: Bootstrap resamples per interval.
        level: Confidence level.

    Returns:
        The :class:`SummaryTable`.

    Raises:
        ConfigError: if there are no rows, a row lacks ``policy``/``user``/a metric or holds a
            non-number, a requested policy has no session, or ``metrics`` is empty.
    """
    if not rows:
        raise ConfigError("rows must not be empty")
    if not metrics:
        raise ConfigError("metrics must not be empty")
    by_policy: dict[str, list[int]] = {}
    for i, row in enumerate(rows):
        for key in ("policy", "user"):
            if key not in row:
                raise ConfigError(f"rows[{i}] lacks {key!r}")
        by_policy.setdefault(str(row["policy"]), []).append(i)
    order = tuple(policies) if policies is not None else tuple(by_policy)
    for p in order:
        if p not in by_policy:
            raise ConfigError(f"policies names {p!r}, which has no session in rows")
    wanted = (*order, reference) if reference in by_policy else order
    values = {
        (p, m): np.array([_value(rows[i], m, i) for i in by_policy[p]])
        for p in wanted
        for m in metrics
    }
    users = {p: [str(rows[i]["user"]) for i in by_policy[p]] for p in wanted}
    cells: dict[tuple[str, str], MetricSummary] = {}
    for p in order:
        pairing = _pairing(users[p], users[reference]) if reference in users else None
        for m in metrics:
            diff: DiffCI | None = None
            if p != reference and reference in users:
                x, y = values[(p, m)], values[(reference, m)]
                if pairing is not None:
                    x, y = x[pairing[0]], y[pairing[1]]
                diff = bootstrap_diff_ci(
                    x,
                    y,
                    paired=pairing is not None,
                    stat=stat,
                    n_boot=n_boot,
                    rng=rng,
                    level=level,
                )
            cells[(p, m)] = MetricSummary(
                p, m, median_iqr(values[(p, m)]), diff, pairing is not None and diff is not None
            )
    return SummaryTable(
        policies=order,
        metrics=tuple(metrics),
        reference=reference,
        stat=stat,
        level=float(level),
        n_boot=n_boot,
        n_sessions={p: len(by_policy[p]) for p in order},
        cells=cells,
    )


def _check_boot_args(stat: str, n_boot: int, level: float) -> None:
    """The bootstrap functions' shared arguments, checked (ConfigError naming the argument)."""
    if stat not in ("mean", "median"):
        raise ConfigError(f"stat must be 'mean' or 'median', got {stat!r}")
    if isinstance(n_boot, bool) or not isinstance(n_boot, int) or n_boot < 100:
        raise ConfigError(f"n_boot must be an int >= 100, got {n_boot!r}")
    if not (isinstance(level, int | float) and 0.0 < level < 1.0):
        raise ConfigError(f"level must lie in (0, 1), got {level!r}")
