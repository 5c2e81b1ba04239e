"""The front door stays a front door: a short README, short guides about the project on any
machine, and a documentation site that builds without a warning."""

from __future__ import annotations

import importlib.util
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
DOCS = REPO / "docs"
README_LINES = 250
GUIDE_LINES = 300
#: The lab notebook: every experiment with the machine and load it ran under, beside the README and
#: not among the guides the site builds.
HISTORY = REPO / "HISTORY.md"
#: A page that describes its writer's machine instead of the project: the machine itself, a count
#: of its cores, its load, the jobs sharing it, a CPU model.
MACHINE = re.compile(
    r"\b(this|our|the development|the (2|two)-core) (2-core |two-core )?(machine|computer|box)\b"
    r"|\b2-core\b|\bon (the|these) 2 cores\b"
    r"|\b(\d+|one|two|four|eight|both) (\w+ )?(cores|CPUs)\b"
    r"|\bload (average|of other jobs|\(1 min\))|\(load [\d.]|\bload [\d.]+\b"
    r"|\b(shared with|busy with|held by) (\w+ )?(other|another) (\w+ )?(jobs?|sessions?|users?)\b"
    r"|\bother jobs\b"
    r"|\b(Xeon|EPYC|Opteron|Ryzen|Threadripper|Core i[3579]|Graviton|Apple M[1-9])\b",
    re.IGNORECASE,
)
#: A test file or a guide named in code or prose.
NAMED = re.compile(r"\b(?:tests/test_\w+\.py|docs/[\w/]+\.md)\b")
#: The tracked files that may name one.
NAMING = (".py", ".md", ".yml", ".yaml", ".toml", ".cfg", ".txt")


def _guides() -> list[Path]:
    """Every page the site builds (all of ``docs/``; the README is its home page)."""
    return sorted(DOCS.rglob("*.md"))


def test_the_readme_is_short() -> None:
    lines = len((REPO / "README.md").read_text(encoding="utf-8").splitlines())
    assert lines <= README_LINES


@pytest.mark.parametrize("page", _guides(), ids=lambda p: str(p.relative_to(DOCS)))
def test_every_guide_is_short(page: Path) -> None:
    assert len(page.read_text(encoding="utf-8").splitlines()) <= GUIDE_LINES


def test_no_page_speaks_of_the_machine_it_was_written_on() -> None:
    found = [
        f"{page.relative_to(REPO)}:{i}: {line.strip()}"
        for page in [REPO / "README.md", *_guides()]
        for i, line in enumerate(page.read_text(encoding="utf-8").splitlines(), 1)
        if MACHINE.search(line)
    ]
    assert found == []


def test_the_pattern_finds_a_machine() -> None:
    for talk in (
        "On this 2-core machine, shared with",
        "measured on our machine",
        "with 2 CPU cores, evaluations included",
        "on two CPU cores shared with another job",
        "when both cores are free",
        "one machine, 2 free cores",
        "other jobs idle (load 0.8)",
        "the machine's load average was 2.5",
        "twice that with other jobs on the CPU",
        "on an Intel Xeon Gold 6248",
        "an AMD EPYC 7B13",
    ):
        assert MACHINE.search(talk), talk
    for prose in (
        "`--workers N` (default: the usable cores)",
        "a core the loop does not share (`taskset`, `isolcpus`)",
        "load, validate, check before motion",
        "10^5 sessions are then about 2 core-hours",
        "4 x `c7i.8xlarge` (128 vCPUs; about USD 1.4 per hour each on demand)",
        "any x86-64 CPU with AVX2 and FMA",
        "under heavy load, sessions are stopped within a second",
        "PhraseGraph.load(default_graph_path('lc'))",
    ):
        assert not MACHINE.search(prose), prose


def test_the_history_is_beside_the_readme_not_a_guide() -> None:
    import yaml

    nav = yaml.safe_load((REPO / "mkdocs.yml").read_text(encoding="utf-8"))["nav"]
    assert HISTORY.is_file()
    assert not [p for p in DOCS.rglob("*.md") if p.name.lower() == "history.md"]
    assert "history" not in " ".join(page for _, page in _nav_pages(nav)).lower()


def _tracked() -> list[Path]:
    """The repository's tracked files (git's list; every file under it where git is missing)."""
    try:
        out = subprocess.run(
            ["git", "ls-files", "-z"], cwd=REPO, capture_output=True, check=True, timeout=60
        ).stdout.decode()
    except (OSError, subprocess.SubprocessError):
        return [p for p in REPO.rglob("*") if ".git" not in p.parts and p.is_file()]
    return [REPO / name for name in out.split("\0") if name]


def test_every_test_file_and_guide_named_in_code_or_docs_exists() -> None:
    """A docstring, config or page citing a test file (``tests/test_*.py``) or a guide
    (``docs/*.md``) cites one that is there."""
    missing = sorted(
        f"{path.relative_to(REPO)}: {name}"
        for path in _tracked()
        if path.suffix in NAMING and path.is_file()
        for name in set(NAMED.findall(path.read_text(encoding="utf-8", errors="replace")))
        if not (REPO / name).is_file()
    )
    assert missing == []


@pytest.mark.skipif(importlib.util.find_spec("mkdocs") is None, reason="needs the docs extra")
def test_the_site_builds_without_a_warning(tmp_path: Path) -> None:
    env = dict(os.environ, NO_MKDOCS_2_WARNING="1")
    res = subprocess.run(
        [sys.executable, "-m", "mkdocs", "build", "--strict", "--site-dir", str(tmp_path)],
        cwd=REPO,
        env=env,
        capture_output=True,
        text=True,
        timeout=300,
        check=False,
    )
    assert res.returncode == 0, res.stderr[-4000:]
    assert (tmp_path / "api" / "env" / "index.html").is_file()
    assert (tmp_path / "cli" / "index.html").read_text().count("usage: langctrl") > 11


def _nav_pages(items: object) -> list[tuple[str, str]]:
    """``(name, page)`` of every page in the site's navigation."""
    out: list[tuple[str, str]] = []
    for item in items if isinstance(items, list) else []:
        for name, value in item.items():
            if isinstance(value, str):
                out.append((name, value))
            else:
                out.extend(_nav_pages(value))
    return out


def test_the_navigation_calls_each_page_by_its_title() -> None:
    """One name per page: the site's navigation names a page by (a part of) its own title."""
    import yaml

    nav = yaml.safe_load((REPO / "mkdocs.yml").read_text(encoding="utf-8"))["nav"]
    wrong = []
    for name, page in _nav_pages(nav):
        if page == "index.md":
            continue  # the home page is the README
        text = (DOCS / page).read_text(encoding="utf-8")
        title = next(line[2:] for line in text.splitlines() if line.startswith("# "))
        if name.lower() not in title.lower():
            wrong.append(f"{page}: nav {name!r}, title {title!r}")
    assert wrong == []
