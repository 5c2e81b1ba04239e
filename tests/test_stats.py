"""Median/IQR, percentile-bootstrap intervals for differences, and the per-policy summary."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from eval.stats import Stat, bootstrap_diff_ci, median_iqr, summarise
from langenv.errors import ConfigError

values = st.lists(
    st.floats(min_value=-100.0, max_value=100.0, allow_nan=False), min_size=1, max_size=25
)


def test_median_iqr_known_values() -> None:
    s = median_iqr([4.0, 1.0, 3.0, 2.0, 5.0, math.nan])
    assert (s.median, s.q1, s.q3, s.n) == (3.0, 2.0, 4.0, 5)
    assert s.iqr == 2.0
    empty = median_iqr([math.nan])
    assert empty.n == 0 and math.isnan(empty.median)
    with pytest.raises(ConfigError, match="infinite"):
        median_iqr([1.0, math.inf])
    with pytest.raises(ConfigError, match="shape"):
        median_iqr(np.zeros((2, 2)))


@settings(max_examples=40, deadline=None)
@given(
    x=values,
    y=values,
    paired=st.booleans(),
    stat=st.sampled_from(["mean", "median"]),
    seed=st.integers(0, 2**32 - 1),
)
def test_interval_contains_the_estimate(
    x: list[float], y: list[float], paired: bool, stat: Stat, seed: int
) -> None:
    if paired:
        n = min(len(x), len(y))
        x, y = x[:n], y[:n]
    est, lo, hi = bootstrap_diff_ci(
        x,
        y,
        paired=paired,
        stat=stat,
        n_boot=500,
        rng=np.random.default_rng(seed),
    )
    tol = 1e-9 * (1.0 + abs(est))
    assert lo - tol <= est <= hi + tol
    assert lo <= hi


@settings(max_examples=30, deadline=None)
@given(
    base=st.lists(st.floats(min_value=-1.0, max_value=1.0), min_size=5, max_size=25),
    shift=st.floats(min_value=5.0, max_value=50.0),
    sign=st.sampled_from([-1.0, 1.0]),
    paired=st.booleans(),
    stat=st.sampled_from(["mean", "median"]),
    seed=st.integers(0, 2**32 - 1),
)
def test_large_shift_excludes_zero(
    base: list[float], shift: float, sign: float, paired: bool, stat: Stat, seed: int
) -> None:
    y = np.array(base)
    x = y[::-1] + sign * shift  # spread <= 2, shift >= 5
    ci = bootstrap_diff_ci(
        x,
        y,
        paired=paired,
        stat=stat,
        n_boot=500,
        rng=np.random.default_rng(seed),
    )
    assert ci.excludes_zero
    assert np.sign(ci.lo) == np.sign(ci.hi) == sign


@settings(max_examples=30, deadline=None)
@given(x=values, stat=st.sampled_from(["mean", "median"]), seed=st.integers(0, 2**32 - 1))
def test_paired_identical_data_gives_zero_interval(x: list[float], stat: Stat, seed: int) -> None:
    ci = bootstrap_diff_ci(
        x,
        list(x),
        paired=True,
        stat=stat,
        n_boot=200,
        rng=np.random.default_rng(seed),
    )
    assert tuple(ci) == (0.0, 0.0, 0.0)


def test_paired_estimate_is_stat_of_differences() -> None:
    x, y = np.array([1.0, 5.0, 2.0, 8.0]), np.array([0.0, 1.0, 1.0, 1.0])
    rng = np.random.default_rng(0)
    assert bootstrap_diff_ci(x, y, paired=True, stat="median", rng=rng).estimate == 2.5
    assert bootstrap_diff_ci(x, y, paired=False, stat="median", rng=rng).estimate == 2.5
    assert bootstrap_diff_ci(x, y, paired=True, stat="mean", rng=rng).estimate == 3.25
    # pairing removes the between-user spread: a much tighter interval than unpaired
    users = np.linspace(0.0, 20.0, 12)
    a, b = users + 1.0 + 0.1 * np.sin(users), users
    _, plo, phi = bootstrap_diff_ci(a, b, paired=True, rng=np.random.default_rng(1))
    _, ulo, uhi = bootstrap_diff_ci(a, b, paired=False, rng=np.random.default_rng(1))
    assert phi - plo < 0.2 * (uhi - ulo)


def test_coverage_of_the_mean_difference() -> None:
    """Over many normal samples the 90 % interval covers the true difference ~90 % of the time."""
    rng = np.random.default_rng(123)
    hits, trials = 0, 300
    for _ in range(trials):
        x = rng.normal(1.0, 1.0, 30)
        y = rng.normal(0.0, 2.0, 25)
        _, lo, hi = bootstrap_diff_ci(x, y, paired=False, n_boot=1000, rng=rng, level=0.9)
        hits += lo <= 1.0 <= hi
    assert 0.83 <= hits / trials <= 0.96


def test_bootstrap_is_reproducible_and_handles_nan() -> None:
    x, y = [1.0, 2.0, math.nan, 4.0], [0.5, math.nan, 1.0, 1.5]
    a = bootstrap_diff_ci(x, y, paired=True, rng=np.random.default_rng(7))
    b = bootstrap_diff_ci(x, y, paired=True, rng=np.random.default_rng(7))
    assert a == b and a.estimate == pytest.approx(np.mean([0.5, 2.5]))
    nan = bootstrap_diff_ci([math.nan], [1.0], paired=False, rng=np.random.default_rng(0))
    assert all(math.isnan(v) for v in nan)


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"x": [1.0, 2.0], "y": [1.0], "paired": True}, "equal lengths"),
        ({"stat": "mode"}, "stat"),
        ({"n_boot": 10}, "n_boot"),
        ({"level": 1.0}, "level"),
        ({"rng": 0}, "rng"),
        ({"x": [1.0, math.inf]}, "x"),
    ],
)
def test_bootstrap_rejects_bad_arguments(kwargs: dict[str, object], match: str) -> None:
    args: dict[str, object] = {
        "x": [1.0, 2.0],
        "y": [0.0, 1.0],
        "paired": False,
        "rng": np.random.default_rng(0),
    }
    args.update(kwargs)
    with pytest.raises(ConfigError, match=match):
        bootstrap_diff_ci(**args)  # type: ignore[arg-type]


def _rows(rng: np.random.Generator, users: list[str], shift: dict[str, float]) -> list[dict]:
    rows = []
    for p, s in shift.items():
        for k, u in enumerate(users):
            rows.append({"policy": p, "user": u, "abs_am": s + 0.1 * k + rng.normal(0, 0.05)})
    return rows


def test_summarise_pairs_by_user_and_orders_policies() -> None:
    rng = np.random.default_rng(0)
    users = [f"u{k}" for k in range(10)]
    rows = _rows(rng, users, {"ac": 3.0, "lc-noap": 1.0, "lc": 0.2})
    rng.shuffle(rows)
    table = summarise(rows, ["abs_am"], rng=rng, policies=["ac", "lc-noap", "lc"], n_boot=2000)
    assert table.policies == ("ac", "lc-noap", "lc")
    assert table.n_sessions == {"ac": 10, "lc-noap": 10, "lc": 10}
    ac = table["ac", "abs_am"]
    assert ac.paired and ac.diff is not None and ac.diff.excludes_zero
    assert ac.diff.estimate == pytest.approx(2.8, abs=0.1)  # paired: user effects cancel
    assert ac.spread.median == pytest.approx(3.45, abs=0.1)
    assert table["lc", "abs_am"].diff is None


def test_summarise_unpaired_when_users_differ_and_without_reference() -> None:
    rng = np.random.default_rng(1)
    rows = _rows(rng, ["a", "b", "c"], {"lc": 0.0}) + _rows(rng, ["d", "e"], {"ac": 1.0})
    table = summarise(rows, ["abs_am"], rng=rng, n_boot=500)
    assert table.policies == ("lc", "ac")  # order of first appearance
    assert not table["ac", "abs_am"].paired and table["ac", "abs_am"].diff is not None
    only_ac = summarise(rows, ["abs_am"], rng=rng, policies=["ac"], reference="ppo")
    assert only_ac["ac", "abs_am"].diff is None
    with pytest.raises(ConfigError, match="ppo"):
        summarise(rows, ["abs_am"], rng=rng, policies=["ppo"])
    with pytest.raises(ConfigError, match="coop_mean"):
        summarise(rows, ["coop_mean"], rng=rng)
    with pytest.raises(ConfigError, match="rows"):
        summarise([], ["abs_am"], rng=rng)
