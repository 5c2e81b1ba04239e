"""Gymnasium wrappers for training the learned aligner on ``LangCtrl-v0``.

Each is usable by rl-baselines3-zoo's ``env_wrapper`` key (a class taking the env and keyword
arguments), innermost first::

    env_wrapper:
      - train.wrappers.AlignmentReward: {w_em: 0.5, w_adev: 0.5, w_am_fine: 1.0}
      - train.wrappers.ResidualLCWrapper: {pace_scale: 0.3, choice_scale: 0.5}

* :class:`ResidualLCWrapper`: the agent's action is a bounded correction of the analytic LC action
  (residual RL, :class:`policies.learned.ResidualLC`); the observation gains LC's action and a few
  alignment features.
* :class:`AlignmentReward`: adds the evaluation's own metrics to the env's reward (misalignment at
  base pace ``|t_a - t_x|``, ``|a - 1|`` while speaking, and a fine-resolution ``|AM|`` term).
* :class:`SeedCycle`: resets cycle through a fixed list of seeds (the same held-out users at every
  periodic evaluation).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any, Literal

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from langenv.errors import ConfigError
from policies.learned import ResidualLC, ResidualSpec
from train.shaping import AlignmentShaping

__all__ = ["AlignmentReward", "ResidualLCWrapper", "SeedCycle"]


class ResidualLCWrapper(gym.ActionWrapper[np.ndarray, np.ndarray, np.ndarray]):
    """Residual RL on top of the analytic Language Controller (optionally with its terminal phase).

    The action is a correction ``r`` in ``[-1, 1]^(2 + n_choice)`` added to LC's action computed
    from the latest observation (see :mod:`policies.learned`); ``r = 0`` is exactly LC. The
    observation is the env's, followed by :data:`policies.learned.FEATURES`.

    Args:
        env: A ``LangCtrl-v0`` env (possibly wrapped).
        pace_scale: Largest change of the physical pace command (pace units).
        audio_scale: Largest change of the audio pace command (pace units); ``None``: pace_scale.
        choice_scale: Largest change of the choice action.
        choice_mode: Must equal the env's ``choice_mode`` when given (a safety check for configs).
        terminal: Terminal-phase horizon of the base LC (s; 0: the paper's LC; see
            :class:`policies.learned.ResidualSpec`).
        k_em: Extra feedback of the base-pace misalignment on the base LC's physical pace (1/s;
            0: the paper's LC; see :class:`policies.learned.ResidualSpec`).
        gate_em: The correction is off while ``|t_a - t_x|`` is below it (s; 0: always on; see
            :class:`policies.learned.ResidualSpec`).
        deadband: Dead band of the correction (0: none; see
            :class:`policies.learned.ResidualSpec`).

    Raises:
        ConfigError: if ``choice_mode`` differs from the env's or a scale is invalid.
    """

    def __init__(
        self,
        env: gym.Env[np.ndarray, np.ndarray],
        pace_scale: float = 0.3,
        choice_scale: float = 0.5,
        choice_mode: Literal["target", "scores"] | None = None,
        audio_scale: float | None = None,
        terminal: float = 0.0,
        k_em: float = 0.0,
        gate_em: float = 0.0,
        deadband: float = 0.0,
    ) -> None:
        super().__init__(env)
        base: Any = env.unwrapped
        if choice_mode is not None and choice_mode != base.choice_mode:
            raise ConfigError(
                f"ResidualLCWrapper: choice_mode={choice_mode!r} but the env uses "
                f"{base.choice_mode!r} (pass the same choice_mode in env_kwargs)"
            )
        self.residual_spec = ResidualSpec(
            choice_mode=base.choice_mode,
            max_children=int(base.max_children),
            pace_scale=float(pace_scale),
            choice_scale=float(choice_scale),
            audio_scale=None if audio_scale is None else float(audio_scale),
            decision_hz=int(base.decision_hz),
            terminal=float(terminal),
            k_em=float(k_em),
            gate_em=float(gate_em),
            deadband=float(deadband),
        )
        self.core = ResidualLC(self.residual_spec, base.paces.limits)
        n_obs = int(np.prod(env.observation_space.shape or (0,))) + self.core.n_features
        self.observation_space = spaces.Box(-1.0, 1.0, (n_obs,), np.float32)
        self.action_space = spaces.Box(-1.0, 1.0, (self.residual_spec.action_dim,), np.float32)

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        obs, info = self.env.reset(seed=seed, options=options)
        return self.core.start(obs).astype(np.float32), info

    def step(self, action: np.ndarray) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        obs, reward, terminated, truncated, info = self.env.step(self.action(action))
        # float32, the space's dtype: what a DummyVecEnv stores and a SubprocVecEnv passes on
        # as is, so that both give the same run
        return self.core.observe(obs).astype(np.float32), float(reward), terminated, truncated, info

    def action(self, action: np.ndarray) -> np.ndarray:
        """The env's action for the correction ``action`` (LC plus the bounded correction)."""
        return self.core.action(action)


class AlignmentReward(gym.Wrapper[np.ndarray, np.ndarray, np.ndarray, np.ndarray]):
    """Adds the evaluation's metrics to the reward (terms also reported in ``info``): the terms of
    :class:`train.shaping.AlignmentShaping` (the batched env adds the same), per decision step
    of length ``dt`` (s), with ``info`` after the step:

    * ``reward_em_base = -w_em |t_a - t_x| dt`` while speech or motion goes on (EM at base pace, s);
    * ``reward_adev = -w_adev |a - 1| dt`` while speech goes on;
    * at the end, ``reward_am_fine = -w_am_fine ln(1 + |AM| / am_scale)``, which still rewards
      improvements of a few milliseconds once ``|AM|`` is small (the env's own ``w_am |AM|`` term
      is linear).

    Args:
        env: A ``LangCtrl-v0`` env (possibly wrapped, but not by an observation-changing wrapper
            that drops ``info``).
        w_em: Weight of the base-pace misalignment (1/s^2).
        w_adev: Weight of the audio pace deviation (1/s).
        w_am_fine: Weight of the logarithmic ``|AM|`` term.
        am_scale: Scale (s) of the logarithmic term, > 0.

    Raises:
        ConfigError: for a negative or non-finite weight, or ``am_scale <= 0``.
    """

    def __init__(
        self,
        env: gym.Env[np.ndarray, np.ndarray],
        w_em: float = AlignmentShaping.w_em,
        w_adev: float = AlignmentShaping.w_adev,
        w_am_fine: float = AlignmentShaping.w_am_fine,
        am_scale: float = AlignmentShaping.am_scale,
    ) -> None:
        super().__init__(env)
        self.shaping = AlignmentShaping(w_em, w_adev, w_am_fine, am_scale)
        self._time = 0.0

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        obs, info = self.env.reset(seed=seed, options=options)
        self._time = float(info.get("time", 0.0))
        return obs, info

    def step(self, action: np.ndarray) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        obs, reward, terminated, truncated, info = self.env.step(action)
        now = float(info["time"])
        dt, self._time = now - self._time, now
        am = info.get("am")
        terms = self.shaping.terms(
            dt, float(info["em"]), float(info["a"]), info["motion_done"], info["speech_done"],
            terminated, math.nan if am is None else float(am),
        )  # fmt: skip
        r_em, r_adev, r_am = (float(t) for t in terms)
        info.update(reward_em_base=r_em, reward_adev=r_adev, reward_am_fine=r_am)
        return obs, float(reward) + r_em + r_adev + r_am, terminated, truncated, info


class SeedCycle(gym.Wrapper[np.ndarray, np.ndarray, np.ndarray, np.ndarray]):
    """Reset with the next seed of a fixed list (cyclically) whenever no seed is given.

    Evaluating ``len(seeds)`` episodes then always meets the same users, so periodic evaluations
    during training are comparable.

    Args:
        env: Any env.
        seeds: Seeds to cycle through (non-empty, each >= 0).

    Raises:
        ConfigError: if ``seeds`` is empty or holds a negative or non-integer seed.
    """

    def __init__(self, env: gym.Env[Any, Any], seeds: Sequence[int]) -> None:
        super().__init__(env)
        seeds = list(seeds)
        if not seeds or any(not isinstance(s, int | np.integer) or s < 0 for s in seeds):
            raise ConfigError(f"SeedCycle: seeds must be non-empty ints >= 0, got {seeds!r}")
        self.seeds = [int(s) for s in seeds]
        self._next = 0

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[Any, dict[str, Any]]:
        if seed is None:
            seed = self.seeds[self._next % len(self.seeds)]
            self._next += 1
        return self.env.reset(seed=seed, options=options)
