"""MkDocs hooks (``mkdocs.yml``: ``hooks``): two pages made from their one source at build time.

* ``index.md`` is ``README.md`` (links into ``docs/`` made relative to the site), so the front
  door is written once;
* ``cli.md``'s ``<!-- langctrl: help -->`` becomes every job's ``langctrl JOB --help``, printed
  by the job's own parser (:mod:`langctrl.cli`), so the reference cannot drift from the code.

The docstrings cross-reference in Sphinx's roles (``:class:`~langenv.users.User```), which
Markdown renders as text: they become links to the API reference where it documents the object
(plain code where it does not), and ``:math:`` becomes code.
"""

from __future__ import annotations

import os
import re
from pathlib import Path
from typing import Any

HELP_MARK = "<!-- langctrl: help -->"
ROLE = re.compile(r":(?:class|func|meth|mod|data|attr|exc|obj|const):<code>(~?)([\w.]+)</code>")
MATH = re.compile(r":math:<code>")
WIDTH = "100"  # columns argparse wraps the help to


def _readme(config: Any) -> str:
    text = (Path(config["config_file_path"]).parent / "README.md").read_text(encoding="utf-8")
    return re.sub(r"\]\(docs/", "](", text)


def _help() -> str:
    from langctrl.cli import COMMANDS, build_parser, load

    before = os.environ.get("COLUMNS")
    os.environ["COLUMNS"] = WIDTH
    try:
        parts = ["```text", build_parser().format_help().rstrip(), "```", ""]
        for name, cmd in COMMANDS.items():
            parts += [f"## `langctrl {name}`", ""]
            parts += [f"`python -m langctrl {name}`: {cmd.summary}.", ""]
            parts += ["```text", load(name).build_parser().format_help().rstrip(), "```", ""]
    finally:
        if before is None:
            del os.environ["COLUMNS"]
        else:
            os.environ["COLUMNS"] = before
    return "\n".join(parts)


def on_page_markdown(markdown: str, page: Any, config: Any, files: Any) -> str:
    """MkDocs' hook: the README as the home page, the jobs' help in the CLI page."""
    if page.file.src_uri == "index.md":
        return _readme(config)
    if HELP_MARK in markdown:
        return markdown.replace(HELP_MARK, _help())
    return markdown


def _link(match: re.Match[str]) -> str:
    ident = match[2]
    title = ident.rsplit(".", 1)[-1] if match[1] else ident
    return f'<autoref identifier="{ident}" optional><code>{title}</code></autoref>'


def on_page_content(html: str, page: Any, config: Any, files: Any) -> str:
    """MkDocs' hook: Sphinx roles in the rendered docstrings as links (autorefs resolves them)."""
    return MATH.sub("<code>", ROLE.sub(_link, html))
