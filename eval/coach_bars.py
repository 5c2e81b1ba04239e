"""The coaches' bars across the grid: does a coach earn its place over the policy below it?

A coach earns its place over another policy (the learned coach over ``lc-coach``; ``lc-coach``
over the best analytic policy that ignores intents, ``--base``) when, at the points of the
grid (:mod:`eval.coach_grid`), paired by session:

* the session's length or the mean path error is lower, the 95 % interval of the reduction
  above 0, at :data:`SHARE` (two thirds) of the points or more (``gained``);
* neither is higher (an interval of the increase above 0) at any point (``worse``);
* every one of its sessions ends within :data:`AM_BAR` s (|AM|);
* its legs are in step: at least :data:`LEGS_BAR` of the boundaries within 1 s (the mean of the
  sessions' ``legs_in_step``) and none beyond :data:`SM_FAR` s (``sm_max_abs``);
* no protective stop in a session whose paired session of the other policy has none.

:func:`coach_bars` gives one :class:`Bars` per pair, :func:`bars_markdown` the table that heads
``grid.md``.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

__all__ = [
    "AM_BAR",
    "GAINS",
    "LEGS_BAR",
    "SHARE",
    "SM_FAR",
    "Bars",
    "bar_pairs",
    "bars_markdown",
    "coach_bars",
]

GAINS = ("session_s", "path_error")
"""The metrics a coach may gain on (lower is better for both)."""
SHARE = 2.0 / 3.0
"""The share of the grid's points at which a coach must gain."""
AM_BAR = 1.0
"""Every session's |AM| at most this (s)."""
LEGS_BAR = 0.95
"""The share of leg boundaries within 1 s a coach must keep."""
SM_FAR = 2.0
"""No leg's words more than this from their leg (s)."""
COACH = "lc-coach"


@dataclass(frozen=True)
class Bars:
    """One policy against another across the grid (module docstring).

    Attributes:
        policy: The coach judged.
        against: The policy it must beat.
        points: Points with an interval for the gains.
        gained: Points where session length or path error is lower (interval below 0).
        worse: Points where either is higher (interval above 0).
        sessions: The coach's sessions over the grid.
        within: Of them, ending within :data:`AM_BAR` s.
        legs: The mean share of leg boundaries in step (NaN: no boundary).
        sm_max: The largest |SM| over its sessions (s; NaN: none).
        new_stops: Its protective stops in sessions whose paired session has none.
    """

    policy: str
    against: str
    points: int
    gained: int
    worse: int
    sessions: int
    within: int
    legs: float
    sm_max: float
    new_stops: int

    def failures(self) -> list[str]:
        """The bars it misses, by name (empty: it earns its place)."""
        out = []
        if self.points == 0 or self.gained < math.ceil(SHARE * self.points - 1e-9):
            out.append("gain")
        if self.worse:
            out.append("worse")
        if self.within < self.sessions:
            out.append("|AM|")
        if not (self.legs >= LEGS_BAR or math.isnan(self.legs)):
            out.append("legs")
        if self.sm_max > SM_FAR:
            out.append("SM")
        if self.new_stops:
            out.append("stops")
        return out

    @property
    def verdict(self) -> str:
        """``PASS`` or ``FAIL: bar, bar``."""
        failed = self.failures()
        return "PASS" if not failed else "FAIL: " + ", ".join(failed)


def coach_bars(
    rows: Sequence[Mapping[str, Any]],
    diffs: Mapping[str, Sequence[Mapping[str, Any]]],
    pairs: Sequence[tuple[str, str]],
) -> list[Bars]:
    """The bars of each ``(policy, against)`` in ``pairs``: ``diffs[against]`` holds the paired
    differences from ``against`` (:func:`eval.coach_grid.differences`), ``rows`` the sessions."""
    return [_bars(rows, diffs[against], policy, against) for policy, against in pairs]


def _bars(
    rows: Sequence[Mapping[str, Any]],
    diffs: Sequence[Mapping[str, Any]],
    policy: str,
    against: str,
) -> Bars:
    per_point: dict[object, list[Mapping[str, Any]]] = {}
    for d in diffs:
        if d["policy"] == policy and d["metric"] in GAINS:
            per_point.setdefault(d["point"], []).append(d)
    points = gained = worse = 0
    for ds in per_point.values():
        if all(math.isnan(float(d["lo"])) for d in ds):
            continue
        points += 1
        gained += any(float(d["hi"]) < 0.0 for d in ds)
        worse += any(float(d["lo"]) > 0.0 for d in ds)
    mine = {_key(r): r for r in rows if r["policy"] == policy}
    theirs = {_key(r): r for r in rows if r["policy"] == against}
    legs = [float(r["legs_in_step"]) for r in mine.values()]
    legs = [x for x in legs if not math.isnan(x)]
    sms = [float(r["sm_max_abs"]) for r in mine.values()]
    sms = [x for x in sms if not math.isnan(x)]
    new_stops = sum(_stop(r) and not (k in theirs and _stop(theirs[k])) for k, r in mine.items())
    return Bars(
        policy, against, points, gained, worse, len(mine),
        sum(float(r["abs_am"]) <= AM_BAR for r in mine.values()),
        sum(legs) / len(legs) if legs else math.nan, max(sms) if sms else math.nan, new_stops,
    )  # fmt: skip


def _key(row: Mapping[str, Any]) -> tuple[str, str, str]:
    return str(row["point"]), str(row["exercise"]), str(row["user"])


def _stop(row: Mapping[str, Any]) -> bool:
    return float(row["protective_stop"]) > 0.0


def bar_pairs(policies: Sequence[str], models: Sequence[str], base: str) -> list[tuple[str, str]]:
    """Who is held against whom: each model against ``lc-coach`` when it runs (else ``base``),
    ``lc-coach`` against ``base``."""
    above = COACH if COACH in policies else base
    pairs = [(m, above) for m in models if m != above]
    if COACH in policies and COACH != base:
        pairs.append((COACH, base))
    return pairs


def bars_markdown(bars: Sequence[Bars]) -> str:
    """The table of :class:`Bars`, one row each (empty string for none)."""
    if not bars:
        return ""
    lines = [
        "## The bars: each coach against the policy below it, paired, across the grid",
        "",
        "Gained: points where session length or mean path error is lower (95 % interval below "
        "0; two thirds of the points needed); worse: points where either is higher.",
        "",
        "| coach | against | gained / points | worse | \\|AM\\| <= 1 s | legs in step "
        "| max \\|SM\\| (s) | new stops | verdict |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for b in bars:
        lines.append(
            f"| {b.policy} | {b.against} | {b.gained} / {b.points} | {b.worse} | "
            f"{b.within}/{b.sessions} | {b.legs:.3f} | {b.sm_max:.2f} | {b.new_stops} | "
            f"{b.verdict} |"
        )
    return "\n".join(lines) + "\n"
