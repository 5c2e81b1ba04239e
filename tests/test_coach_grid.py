"""langctrl coach-grid (eval.coach_grid): the grid of listening assumptions, the paired
differences, and a smoke run that resumes."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from eval.coach_grid import COMPARED, DEFAULT_GRID, GridSpec, differences, tally
from langctrl.jobs.coach_grid import main
from langenv.errors import ConfigError
from langenv.users.listening import SOURCES

ROOT = Path(__file__).resolve().parents[1]


def test_the_default_grid_spans_every_assumption_s_documented_range() -> None:
    spec = GridSpec.load(ROOT / DEFAULT_GRID)
    assumed = {k: s.range for k, s in SOURCES.items() if s.kind == "assumption"}
    assert {k: (min(v), max(v)) for k, v in spec.axes.items()} == assumed
    points = spec.points()
    assert points[0].label == "default" and len(points) == 1 + 2 * len(assumed)


def test_one_at_a_time_and_product_designs() -> None:
    axes = {"latency": [0.4, 2.0], "comply": [0.3]}
    one = GridSpec("one-at-a-time", {"hold": 5.0}, axes).points()
    assert [p.label for p in one] == ["default", "latency=0.4", "latency=2", "comply=0.3"]
    assert all(p.params.hold == 5.0 for p in one)
    prod = GridSpec("product", {}, axes).points()
    assert [p.label for p in prod] == ["latency=0.4,comply=0.3", "latency=2,comply=0.3"]
    assert prod[1].params.latency == 2.0 and prod[1].params.comply == 0.3


@pytest.mark.parametrize(
    ("text", "match"),
    [
        ("axes: {latncy: [1.0]}", "unknown field 'latncy'"),
        ("axes: {latency: []}", "non-empty list"),
        ("axes: {latency: [fast]}", "finite number"),
        ("axes: {latency: [0.01]}", "point latency=0.01"),
        ("design: random", "design must be"),
        ("grid: {}", "unknown key"),
    ],
)
def test_a_bad_grid_file_is_named(tmp_path: Path, text: str, match: str) -> None:
    path = tmp_path / "g.yaml"
    path.write_text(text)
    with pytest.raises(ConfigError, match=match) as err:
        GridSpec.load(path)
    assert str(path) in str(err.value)


def _row(point: int, policy: str, user: str, value: float) -> dict[str, object]:
    row: dict[str, object] = {"point": point, "point_label": f"p{point}", "policy": policy,
                              "exercise": "x", "user": user}  # fmt: skip
    row.update(dict.fromkeys(COMPARED, value))
    return row


def test_differences_are_paired_per_point_and_tallied_by_the_good_side() -> None:
    rows = [_row(0, "base", f"u{k}", float(k)) for k in range(6)]
    rows += [_row(0, "coach", f"u{k}", k - 1.0) for k in range(6)]  # 1 lower everywhere
    rows += [_row(1, "base", f"u{k}", float(k)) for k in range(6)]
    rows += [_row(1, "coach", f"u{k}", float(k)) for k in range(5)]  # u5 missing: unpaired
    diffs = differences(rows, ["base", "coach"], "base", n_boot=200)
    first = [d for d in diffs if d["point"] == 0]
    assert {d["metric"] for d in first} == set(COMPARED)
    assert all(d["estimate"] == pytest.approx(-1.0) and d["n"] == 6 for d in first)
    assert all(d["n"] == 5 and d["estimate"] == 0.0 for d in diffs if d["point"] == 1)
    assert tally(diffs, "coach", "session_s") == (1, 0, 2)  # lower is better
    assert tally(diffs, "coach", "content_share") == (0, 1, 2)  # higher is better


def test_smoke_a_tiny_grid_resumes(tmp_path: Path) -> None:
    grid = tmp_path / "g.yaml"
    grid.write_text("axes: {faster: [6.0]}\n")
    out = tmp_path / "out"
    args = ["--grid", str(grid), "--role", "validation", "--users", "1", "--workers", "1",
            "--policies", "lc-fill-end,lc-coach", "--n-boot", "100", "--out", str(out)]  # fmt: skip
    assert main(args) == 0
    for name in ("sessions.csv", "grid.csv", "grid.md", "grid.png", "config.json"):
        assert (out / name).is_file(), name
    assert sorted(p.name for p in (out / "points").iterdir()) == ["000.csv", "001.csv"]
    config = json.loads((out / "config.json").read_text())
    assert config["points"] == ["default", "faster=6"] and not config["test_look"]
    lines = (out / "grid.csv").read_text().splitlines()
    assert len(lines) == 1 + 2 * len(COMPARED)  # lc-coach at two points
    assert main(args) == 2  # out holds files
    (out / "points" / "001.csv").unlink()
    assert main([*args, "--resume"]) == 0  # point 0 kept, point 1 run again
    assert (out / "points" / "001.csv").is_file()
    assert main([*args[:-2], "--users", "2", "--out", str(out), "--resume"]) == 2  # other args


def test_coach_parameters_are_checked_before_any_episode(tmp_path: Path) -> None:
    base = ["--role", "validation", "--users", "1", "--out", str(tmp_path / "o")]
    assert main([*base, "--coach", "relax_c=2"]) == 2
    assert main([*base, "--coach", "nope=1"]) == 2
    assert main([*base, "--policies", "lc,lc-fill-end", "--coach", "relax_c=0.5"]) == 2
    assert main([*base, "--base", "ac"]) == 2
