"""``langctrl``: one command for LangCtrl's jobs (``langctrl JOB ...`` is ``python -m MODULE ...``).

The package sits above every other (``langenv`` < ``policies`` < ``train``, ``eval`` < ``bench``
< ``langctrl``): it names each job's module as a string in :data:`~langctrl.cli.COMMANDS` and
imports only the one asked for, so ``langctrl --help`` loads none of them and no package imports
``langctrl``.
"""

from __future__ import annotations

from langctrl.cli import COMMANDS, Command, build_parser, main

__all__ = ["COMMANDS", "Command", "build_parser", "main"]
