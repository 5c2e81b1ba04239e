"""The coaches' bars across the grid (eval.coach_bars): gains at two thirds of the points, no
point worse, every session within 1 s, legs in step, no new protective stop."""

from __future__ import annotations

import math

import pytest

from eval.coach_bars import Bars, bar_pairs, bars_markdown, coach_bars
from eval.coach_grid import COMPARED, differences


def _row(point: int, policy: str, user: int, length: float, **kw: float) -> dict[str, object]:
    row: dict[str, object] = {"point": point, "point_label": f"p{point}", "policy": policy,
                              "exercise": "x", "user": f"u{user}"}  # fmt: skip
    row.update(dict.fromkeys(COMPARED, 0.0))
    row.update(session_s=length, abs_am=0.2, legs_in_step=1.0, sm_max_abs=0.3,
               protective_stop=0.0)  # fmt: skip
    row.update(kw)
    return row


def _grid(shift: list[float], **kw: float) -> list[dict[str, object]]:
    """Two policies, ``coach`` ``shift[p]`` s longer than ``base`` at point ``p`` (12 people,
    a little spread so the intervals are not points)."""
    rows = []
    for p, d in enumerate(shift):
        for u in range(12):
            base = 10.0 + u
            rows.append(_row(p, "base", u, base))
            rows.append(_row(p, "coach", u, base + d + 0.01 * (u % 3 - 1), **kw))
    return rows


def _bars(rows: list[dict[str, object]]) -> Bars:
    diffs = differences(rows, ["base", "coach"], "base", n_boot=200)
    return coach_bars(rows, {"base": diffs}, [("coach", "base")])[0]


def test_shorter_at_two_thirds_of_the_points_and_never_longer_passes() -> None:
    bars = _bars(_grid([-1.0, -1.0, 0.0]))
    assert (bars.points, bars.gained, bars.worse) == (3, 2, 0)
    assert bars.verdict == "PASS"


@pytest.mark.parametrize(
    ("shift", "kw", "failed"),
    [
        ([-1.0, 0.0, 0.0], {}, ["gain"]),
        ([-1.0, -1.0, 1.0], {}, ["worse"]),
        ([-1.0, -1.0, -1.0], {"abs_am": 1.5}, ["|AM|"]),
        ([-1.0, -1.0, -1.0], {"legs_in_step": 0.9}, ["legs"]),
        ([-1.0, -1.0, -1.0], {"sm_max_abs": 2.5}, ["SM"]),
        ([-1.0, -1.0, -1.0], {"protective_stop": 1.0}, ["stops"]),
    ],
)
def test_each_bar_is_named_when_missed(
    shift: list[float], kw: dict[str, float], failed: list[str]
) -> None:
    bars = _bars(_grid(shift, **kw))
    assert bars.failures() == failed
    assert bars.verdict == "FAIL: " + ", ".join(failed)


def test_a_stop_the_other_policy_also_has_is_not_new() -> None:
    rows = _grid([-1.0, -1.0, -1.0])
    for r in rows:
        if r["user"] == "u0":
            r["protective_stop"] = 1.0  # both policies stop with this person
    assert _bars(rows).new_stops == 0


def test_models_are_held_against_lc_coach_and_lc_coach_against_the_base() -> None:
    assert bar_pairs(["lc", "lc-fill-end", "lc-coach", "m"], ["m"], "lc-fill-end") == [
        ("m", "lc-coach"),
        ("lc-coach", "lc-fill-end"),
    ]
    assert bar_pairs(["lc", "lc-fill-end", "m"], ["m"], "lc-fill-end") == [("m", "lc-fill-end")]
    assert bar_pairs(["lc-fill-end"], [], "lc-fill-end") == []


def test_the_table_has_a_row_per_pair() -> None:
    bars = _bars(_grid([-1.0, -1.0, 0.0]))
    text = bars_markdown([bars, bars])
    assert text.count("| coach | base | 2 / 3 | 0 | 36/36 |") == 2 and "PASS" in text
    assert bars_markdown([]) == ""
    assert math.isnan(Bars("a", "b", 0, 0, 0, 0, 0, math.nan, math.nan, 0).sm_max)
