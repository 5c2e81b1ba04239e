"""sessions.csv and summary.md: round trip, findings with PASS/FAIL, tables, atomic writes."""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
import pytest

from eval.metrics import METRIC_COLUMNS, NUMERIC_METRICS
from eval.report import (
    read_sessions_csv,
    render_summary_md,
    study_findings,
    write_sessions_csv,
    write_summary_md,
)
from langctrl.jobs.report import main
from langenv.errors import ConfigError, SessionDataError

POLICIES = ("ac", "lc-noap", "lc")


def synthetic_rows(
    rng: np.random.Generator,
    n_users: int = 12,
    am_scale: dict[str, float] | None = None,
    within: dict[str, float] | None = None,
) -> list[dict[str, float | str]]:
    """Rows like langctrl compare writes: |AM| typical size and share of natural audio pace."""
    am_scale = am_scale or {"ac": 2.0, "lc-noap": 0.8, "lc": 0.3}
    within = within or {"ac": 1.0, "lc-noap": 0.5, "lc": 0.75}
    rows: list[dict[str, float | str]] = []
    for p in am_scale:
        for k in range(n_users):
            t_motion = 11.5 + rng.normal(0.0, 1.0)
            am = am_scale[p] * rng.uniform(0.5, 1.5) * rng.choice([-1.0, 1.0])
            a_dev = 0.0 if p == "ac" else rng.uniform(0.02, 0.15)
            rows.append(
                {
                    "policy": p,
                    "user": f"synthetic-{k}",
                    "am": am,
                    "abs_am": abs(am),
                    "em_mean_abs": abs(am) * rng.uniform(0.5, 1.0),
                    "a_mean": 1.0 - a_dev,
                    "a_dev": a_dev,
                    "a_within_0_1": min(1.0, max(0.0, within[p] + rng.normal(0.0, 0.05))),
                    "voice_natural": min(1.0, max(0.0, within[p] + rng.normal(0.1, 0.05))),
                    "pause_share": rng.uniform(0.2, 0.4),
                    "filler_share": 0.0 if p != "lc" else rng.uniform(0.0, 0.05),
                    "content_share": rng.uniform(0.4, 0.7),
                    "p_mean": 1.0 if p == "ac" else rng.uniform(0.9, 1.1),
                    "coop_mean": rng.uniform(0.7, 1.0),
                    "t_motion": t_motion,
                    "t_speech": t_motion + am,
                    "return": -rng.uniform(5.0, 50.0),
                    # legs: LC speaks a marked graph, the baselines one wording (no legs)
                    "sm_max_abs": 0.25 * (k % 3) if p == "lc" else math.nan,
                    "legs_in_step": 1.0 - 0.5 * (k % 2) if p == "lc" else math.nan,
                    # not drawn from rng: the draws of the columns above stay as they were
                    "path_error": 0.002 + 0.0001 * k,
                    "effort": 4.0 + 0.5 * k,
                }
            )
    return rows


def findings_table(text: str) -> list[list[str]]:
    section = text.split("## Findings")[1].split("##")[0]
    return [split_row(line) for line in section.splitlines() if re.match(r"\| \d", line)]


def split_row(line: str) -> list[str]:
    """Cells of a markdown table row (escaped pipes stay inside cells)."""
    return [c.strip().replace("\\|", "|") for c in re.split(r"(?<!\\)\|", line)[1:-1]]


def test_sessions_csv_round_trip(tmp_path: Path) -> None:
    rows = synthetic_rows(np.random.default_rng(0), n_users=3)
    rows[0]["a_mean"] = math.nan
    for r in rows:
        r["seed"] = 7.0
    path = write_sessions_csv(rows, tmp_path / "sessions.csv")
    header = path.read_text().splitlines()[0].split(",")
    assert header == [*METRIC_COLUMNS, "seed"]
    back = read_sessions_csv(path)
    assert len(back) == len(rows)
    for a, b in zip(rows, back, strict=True):
        assert (a["policy"], a["user"]) == (b["policy"], b["user"])
        for key in (*NUMERIC_METRICS, "seed"):
            x, y = float(a[key]), float(b[key])
            assert (math.isnan(x) and math.isnan(y)) or x == y, key  # full precision


def test_sessions_csv_rejects_incomplete_rows(tmp_path: Path) -> None:
    rows = synthetic_rows(np.random.default_rng(0), n_users=2)
    del rows[3]["p_mean"]
    with pytest.raises(ConfigError, match=r"rows\[3\].*p_mean"):
        write_sessions_csv(rows, tmp_path / "sessions.csv")
    with pytest.raises(ConfigError, match="empty"):
        write_sessions_csv([], tmp_path / "sessions.csv")
    assert list(tmp_path.iterdir()) == []


def test_read_sessions_csv_errors_name_the_file(tmp_path: Path) -> None:
    short = tmp_path / "short.csv"
    short.write_text("policy,user,am\nlc,u1,0.3\n")
    with pytest.raises(SessionDataError, match=r"short\.csv.*abs_am"):
        read_sessions_csv(short)
    bad = tmp_path / "bad.csv"
    write_sessions_csv(synthetic_rows(np.random.default_rng(0), n_users=1), bad)
    lines = bad.read_text().splitlines()
    cells = lines[2].split(",")
    cells[METRIC_COLUMNS.index("p_mean")] = "fast"
    lines[2] = ",".join(cells)
    bad.write_text("\n".join(lines) + "\n")
    with pytest.raises(SessionDataError, match=r"bad\.csv, line 3.*p_mean"):
        read_sessions_csv(bad)
    with pytest.raises(SessionDataError, match="missing"):
        read_sessions_csv(tmp_path / "missing.csv")


def test_findings_pass_on_data_that_shows_them() -> None:
    rows = synthetic_rows(np.random.default_rng(1))
    f = study_findings(rows)
    assert [x.verdict for x in f] == ["PASS", "PASS", "PASS"]
    lc_abs = [float(r["abs_am"]) for r in rows if r["policy"] == "lc"]
    assert f"LC {np.median(lc_abs):.2f} s" in f[0].measured
    assert f"max {max(lc_abs):.2f} s; 12/12" in f[1].measured


def test_findings_fail_when_the_data_disagrees() -> None:
    rng = np.random.default_rng(2)
    rows = synthetic_rows(
        rng,
        am_scale={"ac": 0.3, "lc-noap": 0.8, "lc": 2.0},
        within={"ac": 1.0, "lc-noap": 0.8, "lc": 0.4},
    )
    f = study_findings(rows)
    assert [x.verdict for x in f] == ["FAIL", "FAIL", "FAIL"]
    lc_within = sum(1 for r in rows if r["policy"] == "lc" and float(r["abs_am"]) <= 1.0)
    assert f"{lc_within}/12 sessions" in f[1].measured


def test_findings_not_checked_without_the_policies() -> None:
    rows = [r for r in synthetic_rows(np.random.default_rng(3)) if r["policy"] != "lc-noap"]
    f = study_findings(rows)
    assert [x.verdict for x in f] == ["n/a", "PASS", "n/a"]
    assert "LC-noAP" in f[0].measured


def test_summary_markdown(tmp_path: Path) -> None:
    rows = synthetic_rows(np.random.default_rng(4))
    path = write_summary_md(
        rows,
        tmp_path / "summary.md",
        rng=np.random.default_rng(0),
        policies=list(POLICIES),
        n_boot=1000,
        figure="summary.png",
    )
    text = path.read_text()
    assert "![Distributions per controller](summary.png)" in text
    assert [row[-1] for row in findings_table(text)] == ["**PASS**"] * 3
    # every table row has as many cells as its header
    for block in re.findall(r"((?:^\|.*\|$\n?)+)", text, flags=re.M):
        widths = {len(split_row(line)) for line in block.strip().splitlines()}
        assert len(widths) == 1, block
    # per-controller table: columns in the order given, medians and quartiles as computed
    spread = text.split("## Per controller")[1].split("##")[0]
    header = split_row(spread.strip().splitlines()[2])
    assert header == ["metric", "AC (n=12)", "LC-noAP (n=12)", "LC (n=12)"]
    ac_abs = [float(r["abs_am"]) for r in rows if r["policy"] == "ac"]
    q1, med, q3 = np.percentile(ac_abs, [25, 50, 75])
    assert f"| \\|AM\\| (s) | {med:.2f} [{q1:.2f}, {q3:.2f}] |" in spread
    # differences: paired by user, AC's |AM| clearly above LC's
    diffs = text.split("## Differences")[1].split("##")[0]
    assert "AC - LC (paired by user)" in diffs
    ac_row = next(
        cells for cells in map(split_row, diffs.splitlines()) if cells[:1] == ["|AM| (s)"]
    )
    assert ac_row[1].startswith("+") and ac_row[1].endswith("*")
    assert "## How to read this" in text


def test_summary_is_reproducible_and_written_atomically(tmp_path: Path) -> None:
    rows = synthetic_rows(np.random.default_rng(5), n_users=6)
    texts = [render_summary_md(rows, rng=np.random.default_rng(9), n_boot=500) for _ in range(2)]
    assert texts[0] == texts[1]
    path = tmp_path / "summary.md"
    path.write_text("previous run")
    broken: list[dict[str, float | str]] = [
        *rows,
        {"policy": "lc", "user": "x"},
    ]  # lacks every metric
    with pytest.raises(ConfigError, match="lacks metric"):
        write_summary_md(broken, path, rng=np.random.default_rng(0), n_boot=500)
    assert path.read_text() == "previous run"
    assert [p.name for p in tmp_path.iterdir()] == ["summary.md"]


def test_summary_without_reference_or_nan_metrics() -> None:
    rows = synthetic_rows(np.random.default_rng(6), n_users=4)
    for r in rows:
        if r["policy"] == "ac":
            r["a_mean"] = math.nan
    text = render_summary_md(rows, reference="ppo", rng=np.random.default_rng(0), n_boot=200)
    assert "No sessions of the reference PPO" in text and "taken against" not in text
    a_row = next(split_row(line) for line in text.splitlines() if line.startswith("| mean a |"))
    assert a_row[1] == "n/a" and a_row[2] != "n/a"


def test_cli_regenerates_summary(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    csv_path = write_sessions_csv(
        synthetic_rows(np.random.default_rng(7), n_users=4), tmp_path / "sessions.csv"
    )
    assert main([str(csv_path), "--n-boot", "200", "--policies", "lc,ac"]) == 0
    text = (tmp_path / "summary.md").read_text()
    assert "| metric | LC (n=4) | AC (n=4) |" in text
    assert "summary.md" in capsys.readouterr().out


def test_a_table_of_an_older_run_without_the_speech_shares_reads_as_nan(tmp_path: Path) -> None:
    rows = synthetic_rows(np.random.default_rng(1), n_users=2)
    for r in rows:
        del r["pause_share"], r["filler_share"], r["voice_natural"], r["content_share"]
    path = write_sessions_csv(rows, tmp_path / "sessions.csv")
    old = tmp_path / "old.csv"
    lines = path.read_text().splitlines()
    header = lines[0].split(",")
    old_cols = ("pause_share", "filler_share", "voice_natural", "content_share")
    keep = [i for i, c in enumerate(header) if c not in old_cols]
    old.write_text("\n".join(",".join(line.split(",")[i] for i in keep) for line in lines) + "\n")
    back = read_sessions_csv(old)
    assert all(math.isnan(float(r["pause_share"])) for r in back)
    assert all(math.isnan(float(r["voice_natural"])) for r in back)
    assert all(math.isnan(float(r["content_share"])) for r in back)
