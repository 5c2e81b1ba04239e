"""Shared test configuration."""

from __future__ import annotations

import os

from hypothesis import settings

# CI runs the property tests with a fixed example sequence, so a run is reproducible and a red
# build always means a change broke something; locally each run explores new examples.
settings.register_profile("ci", derandomize=True, print_blob=True)
if os.environ.get("CI"):
    settings.load_profile("ci")
