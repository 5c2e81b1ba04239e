"""FastETC's tables on disk (``langenv.control.etc_cache``)."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest

from langenv.control import etc_cache
from langenv.control import motion_etc as me
from langenv.control.admittance import AdmittanceParams, VariableAdmittance
from langenv.control.guide import Guide
from langenv.control.trajectory import LineSegment, Trajectory


def _fast(mass: float = 40.0) -> me.FastETC:
    """A small two-leg geometry (fast to tabulate), tables looked up afresh."""
    tr = Trajectory(
        [
            LineSegment(np.zeros(3), np.array([0.2, 0.0, 0.0]), waypoint=True),
            LineSegment(np.array([0.2, 0.0, 0.0]), np.array([0.2, 0.15, 0.0]), waypoint=True),
        ]
    )
    params = AdmittanceParams(mass=mass)
    me._TABLES.clear()
    return me.FastETC(Guide(tr, params), VariableAdmittance(params), u_step=0.05)


@pytest.fixture
def cache_dir(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    root = tmp_path / "etc"
    monkeypatch.setenv("LANGCTRL_ETC_CACHE", str(root))
    return root


def test_tables_from_disk_equal_built_tables(cache_dir: Path) -> None:
    built = _fast()
    files = list(cache_dir.glob("*.npz"))
    assert len(files) == 1
    loaded = _fast()  # the process cache is cleared: read from disk
    np.testing.assert_array_equal(loaded.prm, built.prm)
    np.testing.assert_array_equal(loaded.tab, built.tab)
    assert not loaded.tab.flags.writeable and not loaded.prm.flags.writeable


def test_other_parameters_get_other_tables(cache_dir: Path) -> None:
    a, b = _fast(40.0), _fast(30.0)
    assert len(list(cache_dir.glob("*.npz"))) == 2
    assert not np.array_equal(a.tab, b.tab)


def test_a_damaged_file_is_rebuilt(cache_dir: Path) -> None:
    built = _fast()
    (path,) = cache_dir.glob("*.npz")
    path.write_bytes(b"not an npz")
    again = _fast()
    np.testing.assert_array_equal(again.tab, built.tab)
    with np.load(path) as data:  # replaced by a good file
        np.testing.assert_array_equal(data["tab"], built.tab)


def test_a_truncated_file_is_rebuilt(cache_dir: Path) -> None:
    built = _fast()
    (path,) = cache_dir.glob("*.npz")
    data = path.read_bytes()
    path.write_bytes(data[: len(data) // 2])  # a write cut short, a disk error
    again = _fast()
    np.testing.assert_array_equal(again.tab, built.tab)
    assert path.read_bytes() == data


def test_other_guide_parameters_get_other_tables(cache_dir: Path) -> None:
    """The key holds the guide's parameters and what it derives, not only the admittance's."""
    tr = Trajectory([LineSegment(np.zeros(3), np.array([0.2, 0.0, 0.0]), waypoint=True)])
    params = AdmittanceParams()
    me._TABLES.clear()
    me.FastETC(Guide(tr, params), VariableAdmittance(params), u_step=0.05)
    other = AdmittanceParams(propel_force=2.0 * params.propel_force)
    me.FastETC(Guide(tr, other), VariableAdmittance(params), u_step=0.05)
    assert len(list(cache_dir.glob("*.npz"))) == 2


def test_unreadable_sources_keep_the_tables_in_memory(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("LANGCTRL_ETC_CACHE", str(tmp_path / "etc"))
    monkeypatch.setattr(etc_cache, "_code_digest", None)
    monkeypatch.setattr(etc_cache, "_SOURCE_DIRS", ("no-such-package",))
    monkeypatch.setattr(etc_cache, "_warned", False)
    with pytest.warns(RuntimeWarning, match="cannot be used"):
        fast = _fast()
    assert fast.tab.size > 0 and not (tmp_path / "etc").exists()


def test_the_digest_depends_on_the_code(monkeypatch: pytest.MonkeyPatch) -> None:
    key = ("k", 1.0)
    before = etc_cache.tables_digest(key)
    monkeypatch.setattr(etc_cache, "_code_digest", "another version of the code")
    assert etc_cache.tables_digest(key) != before


def test_off_and_unwritable(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("LANGCTRL_ETC_CACHE", "off")
    assert etc_cache.etc_cache_dir() is None
    ref = _fast()
    blocker = tmp_path / "file"
    blocker.write_text("a file where the directory should be")
    monkeypatch.setenv("LANGCTRL_ETC_CACHE", str(blocker / "etc"))
    monkeypatch.setattr(etc_cache, "_warned", False)
    with pytest.warns(RuntimeWarning, match="cannot be used"):
        again = _fast()
    np.testing.assert_array_equal(again.tab, ref.tab)
    assert os.listdir(tmp_path) == ["file"]
