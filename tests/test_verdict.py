"""eval.verdict: the comparison's verdict on the terminal, plain text when piped."""

from __future__ import annotations

import io
from pathlib import Path

import numpy as np
import pytest

from eval.verdict import STOP_COLUMNS, print_verdict, verdict_table


def rows(stops: str | None = None) -> list[dict[str, float | str]]:
    rng = np.random.default_rng(0)
    out: list[dict[str, float | str]] = []
    for policy, am in (("ac", 3.0), ("lc-noap", 1.0), ("lc", 0.2)):
        for k in range(4):
            row: dict[str, float | str] = {
                "policy": policy,
                "user": f"s{k}",
                "abs_am": am + 0.1 * k,
                "em_mean_abs": am / 2,
                "a_dev": 0.0 if policy == "ac" else 0.1,
                "a_within_0_1": 0.9 if policy == "lc" else 0.2,
                "t_speech": 11.0 + rng.uniform(),
                "truncated": 0.0,
            }
            if stops is not None:
                row[stops] = 1.0 if (policy, k) == ("lc", 2) else 0.0
            out.append(row)
    return out


def test_table_values_per_policy() -> None:
    header, body = verdict_table(rows(), ["ac", "lc-noap", "lc"])
    assert header == [
        "policy", "users", "median |AM| (s)", "mean |EM| (s)", "mean |a - 1|",
        "|a-1|<=0.1 %",
    ]  # fmt: skip
    assert body[0] == ["AC", "4", "3.15", "1.50", "0.000", "20.0"]
    assert body[2][0] == "LC" and body[2][2] == "0.35" and body[2][5] == "90.0"


def test_shares_of_speech_time_appear_when_the_table_has_them() -> None:
    table = rows()
    for r in table:
        r["pause_share"], r["filler_share"] = 0.25, 0.05
    header, body = verdict_table(table, ["ac", "lc-noap", "lc"])
    assert header[-2:] == ["pauses %", "fillers %"]  # rows without a content share
    assert body[2][-2:] == ["25.0", "5.0"]
    for r in table:
        r["content_share"] = 0.625
    header, body = verdict_table(table, ["ac", "lc-noap", "lc"])
    assert header[-1] == "content %" and body[0][-1] == "62.5"


@pytest.mark.parametrize("column", STOP_COLUMNS)
def test_protective_stops_column_appears_when_the_table_has_one(column: str) -> None:
    header, body = verdict_table(rows(column), ["ac", "lc-noap", "lc"])
    assert header[-1] == "protective stops"
    assert [line[-1] for line in body] == ["0", "0", "1"]


def test_plain_when_not_a_terminal() -> None:
    buf = io.StringIO()
    files = [("sessions.csv", "one row per episode"), ("sessions/", "per episode: npz")]
    print_verdict(rows(), ["ac", "lc-noap", "lc"], Path("out/x"), files, file=buf)
    text = buf.getvalue()
    assert "\x1b[" not in text  # no colour codes
    assert not set("─│┃━┏") & set(text)  # no box drawing
    assert text.count("PASS") == 3
    assert "median |AM| orders AC > LC-noAP > LC" in text
    assert str(Path("out/x") / "sessions.csv") in text and "sessions/" in text


def test_rich_on_a_terminal() -> None:
    buf = io.StringIO()
    print_verdict(rows(), ["ac", "lc-noap", "lc"], Path("out"), [], file=buf, terminal=True)
    text = buf.getvalue()
    assert "\x1b[" in text and "PASS" in text


def test_each_share_says_which_statistic_it_is() -> None:
    """The table's share is a mean over sessions, the third finding's pools all speech time, and
    summary.md's is a median: three figures of one measure, each said for what it is."""
    from eval.verdict import SHARES_NOTE

    buf = io.StringIO()
    print_verdict(rows(), ["ac", "lc-noap", "lc"], Path("out"), [], file=buf, terminal=False)
    lines = buf.getvalue().splitlines()
    assert lines[lines.index("study's findings:") - 1] == SHARES_NOTE
    assert "mean over sessions" in SHARES_NOTE and "medians" in SHARES_NOTE
    (third,) = [line for line in lines if "|a - 1| <= 0.1 for a larger share" in line]
    assert "of all speech time (pooled)" in third


def test_one_name_for_the_share_of_speech_time_in_pauses() -> None:
    """compare's column and the exercises' headline name the pause share alike."""
    from eval.exercises import headline_table

    header, _ = verdict_table([{**r, "pause_share": 0.3} for r in rows()], ["ac", "lc-noap", "lc"])
    row = {"exercise": "x", "sessions": 1, "max_am": 0.1, "within": 1, "silence": 0.3, "voice": 1}
    headline = headline_table([row]).splitlines()[0]
    assert "pauses %" in header and "| pauses (mean) |" in headline and "silence" not in headline
