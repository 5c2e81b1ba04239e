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
#: Pages that may exceed the guides' length and speak of where they were measured.
RECORDS = ("history.md",)
#: A page that describes its writer's machine instead of the project.
MACHINE = re.compile(
    r"\b(this|our|the development|the (2|two)-core) (2-core |two-core )?(machine|computer|box)\b"
    r"|\b2-core\b|\bon (the|these) 2 cores\b",
    re.IGNORECASE,
)


def _guides() -> list[Path]:
    return sorted(p for p in DOCS.rglob("*.md") if p.name not in RECORDS)


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
    assert MACHINE.search("On this 2-core machine, shared with")
    assert MACHINE.search("measured on our machine")
    assert not MACHINE.search("with 2 CPU cores, evaluations included")


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
