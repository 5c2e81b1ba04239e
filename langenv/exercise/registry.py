"""The shipped exercises by name, and the one place an exercise argument is resolved.

``SHIPPED_EXERCISES`` maps each file of ``langenv/assets/exercises`` to its name (the file's
stem); docstrings, CLI help and errors read it, nobody keeps a copy of the list.
:func:`resolve_exercise` turns what a user passes (a shipped name, a YAML path or an
:class:`~langenv.exercise.spec.Exercise`) into an exercise; loaded files are kept per process.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from types import MappingProxyType

from langenv.errors import ConfigError
from langenv.exercise.load import load_exercise
from langenv.exercise.spec import STUDY_EXERCISE, Exercise

__all__ = [
    "DEFAULT_EXERCISE",
    "EXERCISES_DIR",
    "SHIPPED_EXERCISES",
    "exercise_path",
    "resolve_exercise",
]

EXERCISES_DIR = Path(__file__).resolve().parents[1] / "assets" / "exercises"
"""Directory of the exercises shipped with the package."""

SHIPPED_EXERCISES: Mapping[str, Path] = MappingProxyType(
    {p.stem: p for p in sorted(EXERCISES_DIR.glob("*.yaml"))}
)
"""The shipped exercise files by name (the file's stem)."""

DEFAULT_EXERCISE = STUDY_EXERCISE
"""The study's exercise (SPEC §2), the env's default."""

_LOADED: dict[tuple[str, int, int, bool], Exercise] = {}


def exercise_path(spec: str | Path) -> Path:
    """The file of a shipped exercise's name, or ``spec`` as a path.

    Raises:
        ConfigError: ``spec`` is neither a shipped name nor an existing file (listing the names).
    """
    name = str(spec)
    if name in SHIPPED_EXERCISES:
        return SHIPPED_EXERCISES[name]
    path = Path(spec)
    if path.is_file():
        return path
    raise ConfigError(
        f"exercise {name!r} is neither a shipped exercise ({', '.join(SHIPPED_EXERCISES)}) nor "
        "an exercise file"
    )


def resolve_exercise(
    spec: str | Path | Exercise | None, *, unwritten_scripts: bool = False
) -> Exercise:
    """An :class:`Exercise` from a shipped name, a YAML path or an exercise (None: the study's).

    A file is read once per process (again when it changes on disk). ``unwritten_scripts``:
    its ``script`` entries may name files not written yet (:func:`load_exercise`).

    Raises:
        ConfigError: an unknown name or a missing file; ExerciseError: a bad file.
    """
    if isinstance(spec, Exercise):
        return spec
    if spec is None:
        spec = DEFAULT_EXERCISE
    if not isinstance(spec, str | Path):
        raise ConfigError(
            f"exercise must be a name, a path or an Exercise, got {type(spec).__name__}"
        )
    path = exercise_path(spec).resolve()
    st = path.stat()
    key = (str(path), st.st_mtime_ns, st.st_size, unwritten_scripts)
    ex = _LOADED.get(key)
    if ex is None:
        ex = _LOADED[key] = load_exercise(path, unwritten_scripts=unwritten_scripts)
    return ex
