"""Every file and folder a job writes gets the user's normal mode (0666 / 0777 less the umask),
as a plain ``open()`` or ``mkdir()`` would make it, including those written under a temporary
name and renamed into place: a lab shares its results."""

from __future__ import annotations

import os
import stat
from collections.abc import Iterator
from pathlib import Path

import pytest

pytestmark = pytest.mark.skipif(os.name != "posix", reason="POSIX file modes")


@pytest.fixture(params=[0o022, 0o027], ids=["umask022", "umask027"])
def mask(request: pytest.FixtureRequest) -> Iterator[int]:
    old = os.umask(request.param)
    try:
        yield request.param
    finally:
        os.umask(old)


def _wrong_modes(root: Path, mask: int, itself: bool = True) -> dict[str, str]:
    """Entries under ``root`` (and ``root`` if ``itself``) whose mode is not the umask's."""
    wrong = {}
    for path in [root, *root.rglob("*")][0 if itself else 1 :]:
        want = (0o777 if path.is_dir() else 0o666) & ~mask
        got = stat.S_IMODE(path.stat().st_mode)
        if got != want:
            wrong[path.relative_to(root.parent).as_posix()] = f"{got:o} (want {want:o})"
    return wrong


def test_the_umask_is_read_without_changing_it(mask: int) -> None:
    from langenv.files import umask

    assert umask() == mask
    assert umask() == mask


def test_temporary_files_and_folders_get_the_users_mode(tmp_path: Path, mask: int) -> None:
    from eval.atomic import make_tmp_dir
    from langenv.files import atomic_write, temp_dir, temp_file

    fd, path = temp_file(tmp_path, prefix=".x.")
    os.close(fd)
    folder = temp_dir(tmp_path, prefix=".d.")
    atomic_write(tmp_path / "table.md", "| a |\n")
    made = make_tmp_dir(tmp_path / "sub" / "out")
    assert {path, folder, made} <= set(tmp_path.rglob("*"))
    assert _wrong_modes(tmp_path, mask, itself=False) == {}


def test_a_compare_job_writes_files_others_can_read(tmp_path: Path, mask: int) -> None:
    """sessions.csv, summary.md, summary.png, the folder and each session's files."""
    from eval.compare import main

    out = tmp_path / "out"
    assert main(["--policies", "ac", "--users", "synthetic:1", "--out", str(out)]) == 0
    assert {"sessions.csv", "summary.md", "summary.png"} <= {p.name for p in out.iterdir()}
    assert _wrong_modes(out, mask) == {}


def test_an_authored_graph_and_a_rendered_wav_get_the_users_mode(tmp_path: Path, mask: int) -> None:
    from langctrl.jobs.speech import main

    script = tmp_path / "s.txt"
    script.write_text("Reach forward.\nAnd back.\n")
    script.chmod(0o666 & ~mask)
    cache = ["--cache-dir", str(tmp_path / "tts")]
    assert main(["author", str(script), "--out", str(tmp_path / "g.yaml"), *cache]) == 0
    trace = tmp_path / "trace.csv"
    trace.write_text("t,audio_pace\n0,1\n3,1\n")
    trace.chmod(0o666 & ~mask)
    wav = tmp_path / "s.wav"
    assert main(["render", str(tmp_path / "g.yaml"), str(trace), str(wav), *cache]) == 0
    assert wav.is_file()
    assert _wrong_modes(tmp_path, mask, itself=False) == {}
