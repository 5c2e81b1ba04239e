"""``LangCtrl-v0`` across worlds: per episode an exercise, a variant of its script and a person.

:class:`WorldEnv` is the training env of a :class:`~langenv.worlds.split.WorldSplit`: at every
reset it draws, from its own generator (seeded by the first ``reset(seed=...)``), an exercise of
``train``, a variant of that exercise's graph (:func:`~langenv.speech.variant.vary_graph`) and a
user seed in ``train_users``; the person is a :class:`~langenv.users.PerturbedUser` reset with
that seed, so a training person is *exactly* the person of that seed in an evaluation, and the
seed ranges being disjoint, no evaluation person was ever trained on. With ``role`` validation or
test it instead cycles through every exercise of the role times the first users of its range, in
a fixed order, on the exercises' own scripts.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import gymnasium as gym
import numpy as np

from langenv.errors import ConfigError
from langenv.speech.variant import vary_graph
from langenv.users.perturbed import PerturbedUser
from langenv.worlds.split import WorldSplit

__all__ = ["WorldEnv"]


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
    env. ``world`` describes the current episode's world, ``current`` is its env.
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
            "graph_t_min": graph.speech_range()[0],
            "graph_t_max": graph.speech_range()[1],
        }
        return obs, {**info, "world": dict(self.world)}

    def step(self, action: np.ndarray) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        return self._env.step(action)

    @property
    def next_user_seed(self) -> int | None:
        """The seed of the next episode's person for a held-out role (its pairs cycle in order);
        None for the train role, whose person is drawn at the reset."""
        if self.role == "train":
            return None
        return int(self._pairs[self._next % len(self._pairs)][1])

    @property
    def current(self) -> Any:
        """The ``LangCtrlEnv`` of the current episode (unwrapped): what a wrapper that steps
        it tick by tick or in compiled runs (``run_law``) drives."""
        return self._env.unwrapped

    def close(self) -> None:
        for env in self.envs.values():
            env.close()
