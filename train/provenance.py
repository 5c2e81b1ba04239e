"""What a training run records about itself: the run's config and the code that trained it.

``run_config.yaml`` and each saved model's ``NAME_config.yaml`` hold the config (hyperparameters,
the arguments through :func:`recorded_args`, the env's residual spec, the phrase graphs trained
on) and the code's version (:func:`code_version`); paths are recorded so as to describe no
machine (:func:`recorded_path`). ``PPOPolicy.load`` reads them back.
"""

from __future__ import annotations

import sys
from dataclasses import asdict
from pathlib import Path
from typing import Any

import numpy as np

from train.config import Run, TrainArgs

__all__ = ["code_version", "config_dict", "recorded_args", "recorded_path"]


def config_dict(run: Run, residual: dict[str, Any], extra: dict[str, Any]) -> dict[str, Any]:
    """A fresh run's config, as ``run_config.yaml`` records it: the hyperparameters, the
    arguments, the env kwargs, the residual spec ``residual`` (empty: none), the phrase graphs,
    the budget, the versions of the code, and ``extra``."""
    import stable_baselines3

    import langenv
    from policies.learned import graph_digest, observation_layout

    graphs = _trained_graphs(run)
    if run.worlds is not None:
        extra = {"worlds": run.worlds.to_dict(), **extra}
    if residual:
        layout = observation_layout(
            int(residual["max_children"]), bool(residual.get("child_intents", False))
        )
        extra = {"observation_layout": layout, **extra}
    return {
        run.args.env_id: _plain(run.hyper),
        "train": recorded_args(run.args),
        "env_kwargs": _plain(run.env_kwargs),
        "residual": residual,
        # every graph trained on, as tables name them (langenv.exercise.script.graph_label);
        # the digest of the one graph a single-graph run trained on (None: several, varied)
        "phrase_graphs": [label for label, _ in graphs],
        "phrase_graph_sha256": (
            graph_digest(graphs[0][1]) if run.worlds is None and len(graphs) == 1 else None
        ),
        "n_envs": run.n_envs,
        "total_timesteps": run.total,
        "versions": {
            **code_version(langenv.__version__),
            "stable_baselines3": stable_baselines3.__version__,
            "python": sys.version.split()[0],
        },
        **extra,
    }


def _trained_graphs(run: Run) -> list[tuple[str, str]]:
    """``(label, ref)`` of each phrase graph the run's envs speak, in first-use order: the
    config's ``env_kwargs.phrase_graph``, else each training exercise's script (across worlds:
    the train role's, before their variants)."""
    from langenv.exercise import resolve_exercise
    from langenv.exercise.script import graph_label

    given = run.env_kwargs.get("phrase_graph")
    if run.worlds is not None:
        names = run.worlds.exercises("train")
        refs = [run.worlds.graphs.get(n, resolve_exercise(n).graph) for n in names]
    elif given is not None:
        refs = [str(given)]
    else:
        exercise = run.env_kwargs.get("exercise")
        listed = exercise if isinstance(exercise, list | tuple) else [exercise]
        refs = [resolve_exercise(ex).graph for ex in listed]
    found = {graph_label(ref): str(ref) for ref in refs}
    return list(found.items())


def code_version(installed: str) -> dict[str, str]:
    """The version of the code that trains: ``{"langctrl": VERSION}`` plus ``git_commit`` (with
    ``+dirty`` for uncommitted changes) when the code runs from a git checkout.

    ``installed`` is ``langenv.__version__`` (the installed package metadata). An editable
    install keeps the metadata of the day it was installed, so when the source tree beside the
    imported ``langenv`` has a ``pyproject.toml`` whose version differs, that version is the
    one recorded (it is the code that runs) and a line on stderr says to reinstall.

    Args:
        installed: The installed metadata's version.
    """
    import subprocess
    import tomllib

    import langenv

    root = Path(langenv.__file__).resolve().parents[1]
    version = installed
    try:
        source = tomllib.loads((root / "pyproject.toml").read_text())["project"]["version"]
    except (OSError, KeyError, tomllib.TOMLDecodeError):
        source = None
    if isinstance(source, str) and source != installed:
        print(
            f"langctrl train: the installed metadata says langctrl {installed} but the code that "
            f"runs is {source} ({root / 'pyproject.toml'}); recording {source} (reinstall: pip "
            "install -e .)",
            file=sys.stderr,
        )
        version = source
    out = {"langctrl": version}
    try:
        commit = subprocess.run(
            ["git", "-C", str(root), "rev-parse", "HEAD"],
            capture_output=True,
            text=True,
            check=True,
        ).stdout.strip()
        dirty = subprocess.run(
            ["git", "-C", str(root), "status", "--porcelain", "--untracked-files=no"],
            capture_output=True,
            text=True,
            check=True,
        ).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return out
    out["git_commit"] = commit + ("+dirty" if dirty else "")
    return out


def _plain(obj: Any) -> Any:
    """A YAML-safe copy (tuples -> lists, paths -> str)."""
    if isinstance(obj, dict):
        return {str(k): _plain(v) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return [_plain(v) for v in obj]
    if isinstance(obj, Path):
        return str(obj)
    if isinstance(obj, np.generic):
        return obj.item()
    return obj


def recorded_path(path: Path | str) -> str:
    """A path as a run's config records it: describing no machine.

    A relative path is kept; an absolute path inside the working directory becomes relative to
    it; any other absolute path (a temporary folder, another disk) is recorded by its name only.

    Args:
        path: The path given to the run.

    Returns:
        A POSIX path string.
    """
    p = Path(path)
    if not p.is_absolute():
        return p.as_posix()
    try:
        return p.relative_to(Path.cwd()).as_posix()
    except ValueError:
        return p.name


def recorded_args(args: TrainArgs | dict[str, Any]) -> dict[str, Any]:
    """:class:`TrainArgs` (or their recorded mapping) as a config records them: plain values,
    paths through :func:`recorded_path`."""
    items = asdict(args) if isinstance(args, TrainArgs) else dict(args)
    path_keys = {"config", "out", "init_from"}
    return {
        k: (recorded_path(v) if (isinstance(v, Path) or k in path_keys) and v is not None else v)
        for k, v in items.items()
    }
