"""The split of training across worlds: exercises and user seeds per role (train, validation,
test), how training varies scripts, and the users' perturbations.

A training config's top-level ``worlds`` section (read by ``python -m train.ppo``; rl-zoo3
ignores it) is a split; the trained model's config records it, and ``python -m eval.generalise``
reads it back from there::

    worlds:
      train: [external_rotation, shoulder_abduction, shoulder_flexion]
      validation: [shoulder_extension]        # model selection (periodic evaluation)
      test: [hand_to_mouth, forearm_rotation] # never seen by training or selection
      train_users: [1000000, 2000000]         # user seeds [lo, hi) of each role
      validation_users: [900000, 900048]
      test_users: [5000000, 5000048]
      graphs: {external_rotation: study}      # a graph other than the exercise's script
      variation: {p_drop: 0.15, tts_rate: [0.85, 1.2]}     # langenv.speech.variant.GraphVariation
      perturbations: {weights: {none: 0.5, tremor: 0.125}} # langenv.users.Perturbations
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

from langenv.errors import ConfigError
from langenv.speech.variant import GraphVariation
from langenv.users.perturbed import Perturbations

__all__ = ["ROLES", "WorldSplit"]

Role = Literal["train", "validation", "test"]
#: The roles of a split, in order.
ROLES: tuple[str, ...] = ("train", "validation", "test")
_KEYS = (
    *ROLES,
    "train_users",
    "validation_users",
    "test_users",
    "graphs",
    "variation",
    "perturbations",
)


def _seed_range(where: str, name: str, value: Any) -> tuple[int, int]:
    ok = isinstance(value, list | tuple) and len(value) == 2
    ok = ok and all(isinstance(v, int) and not isinstance(v, bool) for v in value)
    if not ok or not 0 <= value[0] < value[1]:
        raise ConfigError(
            f"{where}: {name} must be [lo, hi) seeds with 0 <= lo < hi, got {value!r}"
        )
    return int(value[0]), int(value[1])


@dataclass(frozen=True)
class WorldSplit:
    """The exercises and user seeds of each role, and how training worlds vary.

    Attributes:
        train, validation, test: Exercise names or YAML paths; pairwise disjoint, none empty,
            at least two test exercises.
        train_users, validation_users, test_users: User seeds ``[lo, hi)``; pairwise disjoint.
        graphs: Exercise -> phrase graph to speak instead of its script's (a shipped graph's
            name or a YAML path), e.g. the study's graph for the study's exercise.
        variation: How training varies each script (:class:`GraphVariation`).
        perturbations: The users' perturbations (:class:`Perturbations`), in every role.
    """

    train: tuple[str, ...]
    validation: tuple[str, ...]
    test: tuple[str, ...]
    train_users: tuple[int, int] = (1_000_000, 2_000_000)
    validation_users: tuple[int, int] = (900_000, 900_048)
    test_users: tuple[int, int] = (5_000_000, 5_000_048)
    graphs: Mapping[str, str] = field(default_factory=dict)
    variation: GraphVariation = field(default_factory=GraphVariation)
    perturbations: Perturbations = field(default_factory=Perturbations)

    def __post_init__(self) -> None:
        where = "worlds"
        for role in ROLES:
            names = getattr(self, role)
            if isinstance(names, str) or not isinstance(names, Sequence) or not names:
                raise ConfigError(f"{where}: {role} must be a non-empty list of exercises")
            object.__setattr__(self, role, tuple(str(n) for n in names))
        if len(self.test) < 2:
            raise ConfigError(f"{where}: test needs at least two held-out exercises")
        for i, a in enumerate(ROLES):
            for b in ROLES[i + 1 :]:
                both = sorted(set(getattr(self, a)) & set(getattr(self, b)))
                if both:
                    raise ConfigError(f"{where}: {', '.join(both)} in both {a} and {b}")
        ranges = {}
        for role in ROLES:
            name = f"{role}_users"
            ranges[role] = _seed_range(where, name, list(getattr(self, name)))
            object.__setattr__(self, name, ranges[role])
        for i, a in enumerate(ROLES):
            for b in ROLES[i + 1 :]:
                (lo_a, hi_a), (lo_b, hi_b) = ranges[a], ranges[b]
                if lo_a < hi_b and lo_b < hi_a:
                    raise ConfigError(f"{where}: {a}_users and {b}_users overlap")
        if not isinstance(self.graphs, Mapping):
            raise ConfigError(f"{where}: graphs must map exercise -> phrase graph")
        object.__setattr__(self, "graphs", {str(k): str(v) for k, v in self.graphs.items()})
        if not isinstance(self.variation, GraphVariation):
            raise ConfigError(f"{where}: variation must be a GraphVariation")
        if not isinstance(self.perturbations, Perturbations):
            raise ConfigError(f"{where}: perturbations must be Perturbations")

    @classmethod
    def from_dict(cls, data: Mapping[str, Any], where: str = "worlds") -> WorldSplit:
        """The split of a config's ``worlds`` mapping.

        Raises:
            ConfigError: naming ``where`` and the key, for an unknown key or a bad value.
        """
        if not isinstance(data, Mapping):
            raise ConfigError(f"{where}: must be a mapping")
        unknown = sorted(set(data) - set(_KEYS))
        if unknown:
            raise ConfigError(
                f"{where}: unknown key(s) {', '.join(unknown)}; known: {', '.join(_KEYS)}"
            )
        missing = [r for r in ROLES if r not in data]
        if missing:
            raise ConfigError(f"{where}: missing {', '.join(missing)}")
        kw: dict[str, Any] = {
            k: v for k, v in data.items() if k not in ("variation", "perturbations")
        }
        kw["variation"] = GraphVariation.from_dict(
            data.get("variation") or {}, f"{where}: variation"
        )
        kw["perturbations"] = Perturbations.from_dict(
            data.get("perturbations") or {}, f"{where}: perturbations"
        )
        try:
            return cls(**kw)
        except ConfigError as exc:
            raise ConfigError(
                str(exc) if str(exc).startswith(where) else f"{where}: {exc}"
            ) from None

    @classmethod
    def load(cls, path: str | Path) -> WorldSplit:
        """The split of a YAML file's top-level ``worlds`` mapping (a training config, or a
        model's config that recorded it; a config's ``inherit`` is not followed).

        Raises:
            ConfigError: naming the file, when it cannot be read, has no ``worlds`` or a bad one.
        """
        import yaml

        try:
            data = yaml.safe_load(Path(path).read_text())
        except (OSError, yaml.YAMLError) as exc:
            raise ConfigError(f"{path}: cannot read: {exc}") from None
        if not isinstance(data, Mapping) or data.get("worlds") is None:
            raise ConfigError(
                f"{path}: no 'worlds' section (the split of a training across worlds)"
            )
        try:
            return cls.from_dict(data["worlds"])
        except ConfigError as exc:
            raise ConfigError(f"{path}: {exc}") from None

    def to_dict(self) -> dict[str, Any]:
        """Plain data, as a model's config records it (:meth:`from_dict` reads it back)."""
        from dataclasses import asdict

        pert = asdict(self.perturbations)
        pert["weights"] = dict(self.perturbations.weights)
        out: dict[str, Any] = {role: list(getattr(self, role)) for role in ROLES}
        out.update({f"{r}_users": list(getattr(self, f"{r}_users")) for r in ROLES})
        out["graphs"] = dict(self.graphs)
        out["variation"] = {
            k: list(v) if isinstance(v, tuple) else v for k, v in asdict(self.variation).items()
        }
        out["perturbations"] = {k: list(v) if isinstance(v, tuple) else v for k, v in pert.items()}
        return out

    def check(self) -> None:
        """Load and check every exercise (``langctrl exercise check``) and the graph
        each speaks; the graphs must all have the same largest number of choices.

        Raises:
            ConfigError: naming the exercise, for one that fails, or graphs of unequal choices.
        """
        from langenv.exercise import resolve_exercise
        from langenv.exercise.check import check_exercise
        from langenv.speech.graph import PhraseGraph, graph_path

        choices: dict[str, int] = {}
        for role in ROLES:
            for name in getattr(self, role):
                ex = resolve_exercise(name)
                check_exercise(ex)
                graph = self.graphs.get(name, ex.graph)
                choices[name] = PhraseGraph.load(graph_path(graph)).max_children
        if len(set(choices.values())) > 1:
            listed = ", ".join(f"{k}: {v}" for k, v in choices.items())
            raise ConfigError(
                f"worlds: every exercise's graph must offer the same largest number of choices "
                f"(the observation's size); found {listed} (set worlds.graphs)"
            )

    def exercises(self, role: str) -> tuple[str, ...]:
        """The exercises of ``role``."""
        if role not in ROLES:
            raise ConfigError(f"role must be one of {', '.join(ROLES)}, got {role!r}")
        return tuple(getattr(self, role))

    def users(self, role: str) -> tuple[int, int]:
        """The user seeds ``[lo, hi)`` of ``role``."""
        self.exercises(role)
        lo, hi = getattr(self, f"{role}_users")
        return int(lo), int(hi)

    def pairs(self, role: str, n: int) -> list[tuple[str, int]]:
        """``n`` evaluation episodes of ``role``: ``(exercise, user seed)``, every exercise with
        the same first users of the role's range, user-major."""
        exercises = self.exercises(role)
        lo, hi = self.users(role)
        per = math.ceil(n / len(exercises))
        if per > hi - lo:
            raise ConfigError(
                f"worlds: {n} episodes need {per} {role} users, the range has {hi - lo}"
            )
        return [(ex, s) for s in range(lo, lo + per) for ex in exercises][:n]
