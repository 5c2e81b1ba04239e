"""Session CSV loading and validation (langenv.users.session_csv)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from langenv.errors import SessionDataError
from langenv.users.session_csv import OPTIONAL_COLUMNS, Session, load_session, load_sessions

SESSIONS = Path(__file__).parents[2] / "shared" / "sessions"


def _write(tmp_path: Path, text: str, name: str = "s.csv") -> Path:
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    return path


def test_minimal_file_loads_with_optional_columns_absent(tmp_path: Path) -> None:
    path = _write(tmp_path, " T , Cooperation ,label\n0,1,a\n0.5,0.8,b\n1.0,0.9,c\n")
    s = load_session(path)
    assert s.name == "s"
    assert s.path == path
    np.testing.assert_array_equal(s.t, [0.0, 0.5, 1.0])
    np.testing.assert_array_equal(s.cooperation, [1.0, 0.8, 0.9])
    for col in OPTIONAL_COLUMNS:
        assert getattr(s, col) is None
    assert s.columns == ("t", "cooperation")
    assert s.duration == pytest.approx(1.0)
    with pytest.raises(ValueError):
        s.t[0] = 3.0  # read-only


def test_optional_columns_are_read(tmp_path: Path) -> None:
    header = "t,cooperation," + ",".join(OPTIONAL_COLUMNS)
    rows = [
        ",".join(str(v) for v in [0.02 * i, 1.0] + [i] * len(OPTIONAL_COLUMNS)) for i in range(4)
    ]
    s = load_session(_write(tmp_path, header + "\n" + "\n".join(rows) + "\n"))
    for col in OPTIONAL_COLUMNS:
        np.testing.assert_array_equal(getattr(s, col), [0, 1, 2, 3])


@pytest.mark.parametrize(
    ("text", "fragments"),
    [
        ("", ["empty"]),
        ("t,coop\n0,1\n1,1\n", ["missing", "'cooperation'"]),
        ("cooperation\n1\n1\n", ["missing", "'t'"]),
        ("t,cooperation\n0,1\n0.5,nan\n1,1\n", ["'cooperation'", "line 3", "not finite"]),
        ("t,cooperation\n0,1\n0.5,high\n1,1\n", ["'cooperation'", "line 3", "not a number"]),
        ("t,cooperation\n0,1\nabc,1\n", ["'t'", "line 3", "not a number"]),
        ("t,cooperation\n0,1\n1,1\n0.5,1\n", ["'t'", "strictly increasing", "line 4"]),
        ("t,cooperation\n0,1\n1,1\n1,1\n", ["'t'", "strictly increasing"]),
        ("t,cooperation\n0,1\n1,1.2\n", ["'cooperation'", "[0, 1]", "line 3"]),
        ("t,cooperation\n0,1\n1,-0.1\n", ["'cooperation'", "[0, 1]"]),
        ("t,cooperation\n0,1\n1\n", ["line 3", "cells"]),
        ("t,cooperation\n", ["at least 2 rows"]),
        ("t,cooperation\n0,1\n", ["at least 2 rows"]),
        ("t,cooperation,t\n0,1,0\n1,1,1\n", ["'t'", "more than once"]),
        ("t,cooperation,em\n0,1,0\n1,1,x\n", ["'em'", "line 3", "not a number"]),
    ],
)
def test_bad_files_raise_naming_file_and_place(
    tmp_path: Path, text: str, fragments: list[str]
) -> None:
    path = _write(tmp_path, text, "bad_session.csv")
    with pytest.raises(SessionDataError) as info:
        load_session(path)
    message = str(info.value)
    assert "bad_session.csv" in message
    for fragment in fragments:
        assert fragment in message


def test_unreadable_files(tmp_path: Path) -> None:
    with pytest.raises(SessionDataError, match=r"missing\.csv"):
        load_session(tmp_path / "missing.csv")
    binary = tmp_path / "binary.csv"
    binary.write_bytes(b"t,cooperation\n\xff\xfe\x00\x81\n")
    with pytest.raises(SessionDataError, match=r"binary\.csv"):
        load_session(binary)
    with pytest.raises(SessionDataError, match="cannot read"):
        load_session(tmp_path)  # a directory


def test_in_memory_session_is_validated() -> None:
    with pytest.raises(SessionDataError, match="index 1"):
        Session(name="x", t=np.array([0.0, 0.0]), cooperation=np.array([1.0, 1.0]))
    with pytest.raises(SessionDataError, match="'ee_speed'"):
        Session(name="x", t=np.array([0.0, 1.0]), cooperation=np.ones(2), ee_speed=np.ones(3))


def test_load_sessions_directory(tmp_path: Path) -> None:
    _write(tmp_path, "t,cooperation\n0,1\n1,0.5\n", "b.csv")
    _write(tmp_path, "t,cooperation\n0,1\n2,0.5\n", "a.csv")
    _write(tmp_path, "not a session", "notes.txt")
    sessions = load_sessions(tmp_path)
    assert [s.name for s in sessions] == ["a", "b"]
    assert [s.name for s in load_sessions(tmp_path, "b*.csv")] == ["b"]
    with pytest.raises(SessionDataError, match="no session files"):
        load_sessions(tmp_path, "*.tsv")
    with pytest.raises(SessionDataError, match="not a directory"):
        load_sessions(tmp_path / "nowhere")


def test_study_sessions_load() -> None:
    if not SESSIONS.is_dir():
        pytest.skip(f"recorded sessions not found at {SESSIONS}")
    sessions = load_sessions(SESSIONS)
    assert len(sessions) >= 1
    for s in sessions:
        assert s.columns == ("t", "cooperation", *OPTIONAL_COLUMNS)
        assert np.all(np.diff(s.t) > 0)
        assert 5.0 < s.duration < 60.0


def _scaled(tmp_path: Path, scale: float, shift: float = 0.0, name: str = "scaled.csv") -> Path:
    t = np.arange(686) * 0.02 * scale + shift
    rows = "\n".join(f"{float(v)!r},1.0" for v in t)
    return _write(tmp_path, f"t,cooperation\n{rows}\n", name)


@pytest.mark.parametrize(
    ("scale", "shift", "fragment"),
    [
        (1e4, 0.0, "600 s maximum session length"),
        (1e6, 0.0, "600 s maximum session length"),
        (1e-9, 0.0, "minimum spacing"),
        (1.0, -0.5, "must start at or after 0 s"),
    ],
)
def test_time_axis_is_bounded_before_any_allocation(
    tmp_path: Path, scale: float, shift: float, fragment: str
) -> None:
    """Times in ms, in the wrong unit or starting before 0: a named error, not gigabytes."""
    with pytest.raises(SessionDataError) as info:
        load_session(_scaled(tmp_path, scale, shift))
    assert "scaled.csv" in str(info.value) and fragment in str(info.value)


def test_absurd_last_time_is_named(tmp_path: Path) -> None:
    path = _write(tmp_path, "t,cooperation\n0,1\n1e300,1\n", "far.csv")
    with pytest.raises(SessionDataError, match=r"far\.csv.*t=1e\+300"):
        load_session(path)
