"""Shared test configuration."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest
from hypothesis import settings

import langenv.robot  # noqa: F401  (picks MuJoCo's off-screen GL backend before mujoco loads)
from langenv.speech.audio import ClipLibrary

# CI runs the property tests with a fixed example sequence, so a run is reproducible and a red
# build always means a change broke something; locally each run explores new examples.
settings.register_profile("ci", derandomize=True, print_blob=True)
if os.environ.get("CI"):
    settings.load_profile("ci")


WARM_TIMEOUT = 600
"""Seconds the cache warm-up may take (a fresh machine compiles every kernel: about a minute)."""


def _numba_caches() -> list[Path]:
    """The numba cache files the suite's processes share: librosa's and the project's."""
    import importlib.util

    roots = [Path(__file__).resolve().parents[1] / "langenv"]
    spec = importlib.util.find_spec("librosa")
    if spec is not None and spec.origin is not None:
        roots.append(Path(spec.origin).parent)
    found = [p for root in roots for p in root.rglob("__pycache__/*.nb[ic]")]
    if os.environ.get("NUMBA_CACHE_DIR"):  # numba writes every cache there instead
        found += Path(os.environ["NUMBA_CACHE_DIR"]).rglob("*.nb[ic]")
    return found


def _warm() -> subprocess.CompletedProcess[str]:
    env = {**os.environ, "LANGCTRL_ETC_CACHE": "off"}  # build the motion-time tables too
    return subprocess.run(
        [sys.executable, str(Path(__file__).with_name("warm_caches.py"))],
        cwd=Path(__file__).resolve().parents[1],
        env=env,
        capture_output=True,
        text=True,
        timeout=WARM_TIMEOUT,
    )


def pytest_configure(config: pytest.Config) -> None:
    """Under xdist, in the controller, before any worker starts: compile every cached numba
    function once, in one process (``tests/warm_caches.py``), so that the workers load it
    instead of compiling it together. A warm-up that crashes (a cache left corrupt, numba issue
    10128) deletes the shared numba caches and tries once more; a second failure ends the run
    with its output instead of letting every worker crash on it."""
    if hasattr(config, "workerinput") or not getattr(config.option, "numprocesses", None):
        return
    done = _warm()
    if done.returncode != 0:
        for path in _numba_caches():
            path.unlink(missing_ok=True)
        done = _warm()
    if done.returncode != 0:
        pytest.exit(
            f"warming numba's caches failed twice (exit {done.returncode}):\n"
            f"{done.stdout[-2000:]}{done.stderr[-4000:]}",
            returncode=3,
        )


@pytest.fixture(scope="session", autouse=True)
def fresh_etc_cache(tmp_path_factory: pytest.TempPathFactory) -> None:
    """FastETC's disk cache in a directory of this test session (inherited by the scripts the
    tests start): the tests build the tables themselves instead of reading tables a user's runs
    left in ``~/.cache``."""
    os.environ["LANGCTRL_ETC_CACHE"] = str(tmp_path_factory.mktemp("etc-cache"))


@pytest.fixture(scope="session")
def clips(tmp_path_factory: pytest.TempPathFactory) -> ClipLibrary:
    """A :class:`ClipLibrary` whose TTS cache is this test session's (clips synthesised by the
    tests, not read from a user's ``~/.cache``)."""
    return ClipLibrary(cache_dir=tmp_path_factory.mktemp("tts"))


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


@pytest.fixture(scope="session")
def tiny_ppo_models(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, ...]:
    """Two learned aligners of the shipped recipe (``configs/ppo.yaml``), trained in-process
    by ``train.ppo`` for one short rollout each with different seeds: distinct weights, the
    current observation layout, the three files ``PPOPolicy.load`` reads. Built, never stored, so
    no test depends on a binary made for an older observation."""
    from train.config import TrainArgs
    from train.ppo import train

    root = tmp_path_factory.mktemp("tiny_ppo")
    config = root / "tiny.yaml"
    recipe = Path(__file__).resolve().parents[1] / "configs" / "ppo.yaml"
    config.write_text(
        f"inherit: {recipe}\nLangCtrl-v0: {{n_steps: 64, batch_size: 32, n_epochs: 1}}\n"
    )
    models = []
    for seed in (1_000_000, 2_000_000):
        args = TrainArgs(
            config=config,
            out=root / f"s{seed}",
            total_timesteps=64,
            seed=seed,
            n_envs=1,
            vec_env="dummy",
            n_eval_episodes=0,
            progress_bar=False,
            tensorboard=False,
        )
        # given: these arguments win over the config's train section, as on a command line
        models.append(train(args, given={"seed", "out", "n_envs", "n_eval_episodes"}))
    return tuple(models)
