"""``python -m langctrl JOB ...``: the same as the ``langctrl`` command."""

from __future__ import annotations

import sys

from langctrl.cli import main

if __name__ == "__main__":
    sys.exit(main())
