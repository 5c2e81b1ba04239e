"""The results the README and ``docs/results.md`` show are what the code prints.

``tools/results.py --check`` reruns the main job (the one result cheap enough for every run of
the suite) and fails on any difference from the pages; every other section is checked the same
way on demand (``python tools/results.py --check KEY``), and ``--write`` refreshes them.
"""

from __future__ import annotations

import importlib.util
import subprocess
import sys
from pathlib import Path
from types import ModuleType

REPO = Path(__file__).resolve().parents[1]
TOOL = REPO / "tools" / "results.py"


def _tool() -> ModuleType:
    spec = importlib.util.spec_from_file_location("results_tool", TOOL)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # dataclasses look their module up
    spec.loader.exec_module(module)
    return module


def test_every_block_of_the_pages_has_a_section() -> None:
    tool = _tool()
    for page in tool.PAGES:
        keys = tool.blocks((REPO / page).read_text(encoding="utf-8"))
        assert keys, f"{page} shows no checked result"
        assert set(keys) <= set(tool.SECTIONS)
    shown = {k for page in tool.PAGES for k in tool.blocks((REPO / page).read_text())}
    assert shown == set(tool.SECTIONS), "a section no page shows, or a block with no section"


def test_blocks_are_replaced_whole() -> None:
    tool = _tool()
    page = "a\n<!-- results: main -->\nold\n<!-- /results -->\nb\n"
    assert tool.blocks(page) == {"main": "old\n"}
    assert tool._replace(page, {"main": "new\n"}) == page.replace("old", "new")
    assert tool._replace(page, {}) == page


def test_stdout_is_cut_before_the_file_list() -> None:
    tool = _tool()
    out = "\ntable\n  row  \nfiles:\n  out/x\n"
    assert tool.Stdout(stop=r"^files:").extract([out], REPO) == "```text\ntable\n  row\n```\n"


def test_the_main_job_prints_what_the_pages_show(tmp_path: Path) -> None:
    res = subprocess.run(
        [sys.executable, str(TOOL), "--check", "--workdir", str(tmp_path), "main", "main-summary"],
        cwd=REPO,
        capture_output=True,
        text=True,
        timeout=600,
        check=False,
    )
    assert res.returncode == 0, res.stderr[-4000:]
