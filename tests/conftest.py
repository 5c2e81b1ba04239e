"""Shared test configuration."""

from __future__ import annotations

import os

import pytest
from hypothesis import settings

import langenv.robot  # noqa: F401  (picks MuJoCo's off-screen GL backend before mujoco loads)

# CI runs the property tests with a fixed example sequence, so a run is reproducible and a red
# build always means a change broke something; locally each run explores new examples.
settings.register_profile("ci", derandomize=True, print_blob=True)
if os.environ.get("CI"):
    settings.load_profile("ci")


@pytest.fixture(scope="session")
def offscreen_gl() -> None:
    """Skip when no off-screen OpenGL context can be made here (checked on an empty model, so a
    rendering bug of ours never turns into a skip)."""
    import mujoco

    try:
        mujoco.Renderer(mujoco.MjModel.from_xml_string("<mujoco/>"), 8, 8).close()
    except Exception as exc:  # MuJoCo raises several types when no GL context can be made
        backend = os.environ.get("MUJOCO_GL")
        pytest.skip(f"no off-screen OpenGL backend (MUJOCO_GL={backend}): {exc}")
