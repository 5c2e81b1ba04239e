"""Exceptions raised by langenv.

Every error a user can cause with bad input derives from :class:`LangEnvError`, so callers can
catch the package's errors in one place. Messages name the file, field or argument at fault.
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import Any


class LangEnvError(Exception):
    """Base class of every error langenv raises on bad input."""


class ConfigError(LangEnvError, ValueError):
    """A parameter, keyword argument or configuration value is invalid (names the field)."""


class TrajectoryError(ConfigError):
    """A trajectory or segment is malformed (degenerate segment, discontinuity, ...)."""


class PhraseGraphError(LangEnvError, ValueError):
    """A phrase graph file is malformed (names the file and the phrase)."""


class ScriptError(PhraseGraphError):
    """A plain-text speech script is malformed (names the file, line and column)."""


class AudioError(LangEnvError, OSError):
    """A phrase clip cannot be read, synthesised or written (names the file)."""


class SessionDataError(LangEnvError, ValueError):
    """A recorded-session CSV is unreadable or lacks required columns (names the file)."""


class ActionError(LangEnvError, ValueError):
    """An action passed to the environment is NaN, infinite or out of range."""


class DeviceError(LangEnvError, OSError):
    """A device the live mode needs is missing: a display, a sound card or its library."""


class ModelError(LangEnvError, ValueError):
    """A saved model (a learned policy's files) is unreadable or inconsistent (names the file)."""


class ObservationLayoutError(ModelError):
    """A saved model was trained for another observation layout than the one it would read.

    Attributes:
        path: The model file (or its config) at fault.
        expected: The layout the code and the phrase graph give now: ``size=N signature=HEX``.
        found: The layout the model was trained with (its recorded signature, or its input size).
    """

    def __init__(self, path: object, expected: str, found: str, hint: str = "") -> None:
        self.path, self.expected, self.found = path, expected, found
        tail = f"; {hint}" if hint else ""
        super().__init__(
            f"{path}: trained for another observation layout: the model reads {found}, "
            f"this code and phrase graph give {expected}{tail}"
        )


class GraphChoicesError(ModelError):
    """A learned model cannot act on the phrase graph it is to speak: the graph offers more
    choices at a vertex than the model can read or choose among, and it cannot be widened.

    Attributes:
        path: The model file.
        graph: The graph, as tables name it (a shipped graph's name or the YAML's path).
        model_choices: The largest number of choices the model was trained for.
        graph_choices: The graph's largest number of choices.
    """

    def __init__(
        self, path: object, graph: str, model_choices: int, graph_choices: int, hint: str = ""
    ) -> None:
        self.path, self.graph = path, graph
        self.model_choices, self.graph_choices = model_choices, graph_choices
        tail = f"; {hint}" if hint else ""
        super().__init__(
            f"{path}: cannot speak the phrase graph {graph}: it offers up to {graph_choices} "
            f"choices at a phrase, the model was trained for {model_choices}{tail}"
        )


class ExerciseError(ConfigError):
    """An exercise file is malformed, or its exercise is unsafe for the arm (names the file).

    Attributes:
        problems: Every problem found, as :class:`~langenv.exercise.spec.Problem` records
            ``(kind, leg, point, detail)``; ``kind`` is one of
            :data:`~langenv.exercise.spec.PROBLEM_KINDS` (stable: tests assert on it).
        path: The exercise file, or None for an exercise built in code.
    """

    def __init__(self, problems: Iterable[Any], path: object = None) -> None:
        self.problems: tuple[Any, ...] = tuple(problems)
        self.path = path
        label = str(path) if path is not None else "<exercise>"
        lines = [f"{label}: {p}" for p in self.problems] or [f"{label}: invalid exercise"]
        super().__init__("\n".join(lines))
