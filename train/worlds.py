"""Training across worlds: per episode an exercise, a variant of its script and a person.

A config's top-level ``worlds`` section (read by ``python -m train.ppo``; rl-zoo3 ignores it)
fixes the split, which the trained model's config records::

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

:class:`WorldEnv` is the training env: at every reset it draws, from its own generator (seeded
by the first ``reset(seed=...)``), an exercise of ``train``, a variant of that exercise's graph
(:func:`~langenv.speech.variant.vary_graph`) and a user seed in ``train_users``; the person is a
:class:`~langenv.users.PerturbedUser` reset with that seed, so a training person is *exactly* the
person of that seed in an evaluation, and the seed ranges being disjoint, no evaluation person
was ever trained on. With ``role`` validation or test it instead cycles through every exercise of
the role times the first users of its range, in a fixed order, on the exercises' own scripts.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, Literal

import gymnasium as gym
import numpy as np

from langenv.errors import ConfigError
from langenv.speech.variant import GraphVariation, vary_graph
from langenv.users.perturbed import Perturbations, PerturbedUser

__all__ = ["ROLES", "WorldEnv", "WorldSplit"]

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
        """Load and check every exercise (``python -m langenv.exercise check``) and the graph
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


class WorldEnv(gym.Env[np.ndarray, np.ndarray]):
    """``LangCtrl-v0`` across the worlds of a split (module docstring).

    Args:
        split: The split.
        role: ``"train"`` (draw worlds) or ``"validation"``/``"test"`` (cycle through
            :meth:`WorldSplit.pairs`).
        env_kwargs: Further ``LangCtrl-v0`` arguments (not ``exercise``/``phrase_graph``).
        n_episodes: With validation or test, how many pairs to cycle through.

    The attributes ``choice_mode``, ``max_children``, ``decision_hz`` and ``paces`` are the
    (common) ones of its envs, so ``train.wrappers.ResidualLCWrapper`` wraps it as it wraps one
    env. ``world`` describes the current episode's world.
    """

    metadata = {"render_modes": []}  # noqa: RUF012

    def __init__(
        self,
        split: WorldSplit,
        role: str = "train",
        env_kwargs: Mapping[str, Any] | None = None,
        n_episodes: int = 1,
    ) -> None:
        import langenv

        super().__init__()
        kwargs = dict(env_kwargs or {})
        for key in ("exercise", "phrase_graph", "users", "render_mode"):
            kwargs.pop(key, None)
        self.split, self.role = split, role
        names = split.exercises(role)
        self.envs: dict[str, Any] = {}
        for name in names:
            graph = split.graphs.get(name)
            extra: dict[str, Any] = {"phrase_graph": graph} if graph is not None else {}
            self.envs[name] = gym.make(langenv.ENV_ID, exercise=name, **extra, **kwargs)
        first = next(iter(self.envs.values()))
        sizes = {e.observation_space.shape for e in self.envs.values()}
        if len(sizes) > 1:
            raise ConfigError(
                f"worlds: {role} exercises give observations of sizes {sorted(sizes)}"
            )
        self.observation_space = first.observation_space
        self.action_space = first.action_space
        base = first.unwrapped
        self.choice_mode, self.max_children = base.choice_mode, base.max_children
        self.decision_hz, self.paces = base.decision_hz, base.paces
        self.graphs = {n: e.unwrapped.graph for n, e in self.envs.items()}
        self.user = PerturbedUser(split.perturbations)
        self._pairs = split.pairs(role, n_episodes) if role != "train" else []
        self._next = 0
        self._rng = np.random.default_rng()
        self._env: Any = first
        self.world: dict[str, Any] = {}

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        if self.role == "train":
            if seed is not None:
                self._rng = np.random.default_rng(seed)
            names = tuple(self.envs)
            name = names[int(self._rng.integers(len(names)))]
            env = self.envs[name]
            env.unwrapped.use_phrase_graph(
                vary_graph(self.graphs[name], self._rng, self.split.variation)
            )
            user_seed = int(self._rng.integers(*self.split.users("train")))
        else:
            name, user_seed = self._pairs[self._next % len(self._pairs)]
            self._next += 1
            env = self.envs[name]
        self._env = env
        obs, info = env.reset(seed=user_seed, options={"user": self.user})
        graph = env.unwrapped.graph
        self.world = {
            "exercise": name,
            "user_seed": user_seed,
            "perturbation": self.user.kind,
            "graph_t_min": graph.t_min(graph.start),
            "graph_t_max": graph.t_max(graph.start),
        }
        return obs, {**info, "world": dict(self.world)}

    def step(self, action: np.ndarray) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        return self._env.step(action)

    def close(self) -> None:
        for env in self.envs.values():
            env.close()
