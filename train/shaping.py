"""Training's reward shaping, written once: the terms :class:`train.wrappers.AlignmentReward`
adds to a single env's reward and :class:`train.vec_env.BatchedVecEnv` adds to a batch's.

:class:`AlignmentShaping` holds the weights (with their one set of defaults) and computes the
terms on arrays, one entry per session (a single env passes scalars); the wrapper and the batch
only gather the step's values from their ``info`` and keep each session's clock.
``tests/test_train_batched.py`` checks that both give the same shaped rewards on the same
episodes.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, fields
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from langenv.errors import ConfigError

__all__ = ["AlignmentShaping"]


@dataclass(frozen=True)
class AlignmentShaping:
    """The evaluation's metrics as reward terms (the weights of ``AlignmentReward``).

    Per decision step of length ``dt`` (s):

    * ``reward_em_base = -w_em |t_a - t_x| dt`` while speech or motion goes on (EM at base pace, s);
    * ``reward_adev = -w_adev |a - 1| dt`` while speech goes on;
    * at the end (terminated, with an ``AM``), ``reward_am_fine = -w_am_fine ln(1 + |AM| /
      am_scale)``, which still rewards improvements of a few milliseconds once ``|AM|`` is small
      (the env's own ``w_am |AM|`` term is linear).

    Attributes:
        w_em: Weight of the base-pace misalignment (1/s^2), finite and >= 0.
        w_adev: Weight of the audio pace deviation (1/s), finite and >= 0.
        w_am_fine: Weight of the logarithmic ``|AM|`` term, finite and >= 0.
        am_scale: Scale (s) of the logarithmic term, finite and > 0.

    Raises:
        ConfigError: for a negative or non-finite weight, or ``am_scale <= 0``.
    """

    w_em: float = 0.5
    w_adev: float = 0.5
    w_am_fine: float = 1.0
    am_scale: float = 0.02

    def __post_init__(self) -> None:
        for name in ("w_em", "w_adev", "w_am_fine"):
            w = getattr(self, name)
            if not (math.isfinite(w) and w >= 0.0):
                raise ConfigError(f"AlignmentReward: {name} must be finite and >= 0, got {w!r}")
        if not (math.isfinite(self.am_scale) and self.am_scale > 0.0):
            raise ConfigError(
                f"AlignmentReward: am_scale must be finite and > 0, got {self.am_scale!r}"
            )
        for f in fields(self):
            object.__setattr__(self, f.name, float(getattr(self, f.name)))

    @classmethod
    def from_kwargs(cls, kwargs: Mapping[str, Any]) -> AlignmentShaping:
        """The shaping of a config's ``AlignmentReward: {...}`` keyword arguments.

        Raises:
            ConfigError: for an argument it does not take, or a bad value.
        """
        unknown = sorted(set(kwargs) - {f.name for f in fields(cls)})
        if unknown:
            raise ConfigError(f"AlignmentReward: unknown argument(s) {', '.join(unknown)}")
        return cls(**kwargs)

    def terms(
        self,
        dt: ArrayLike,
        em: ArrayLike,
        a: ArrayLike,
        motion_done: ArrayLike,
        speech_done: ArrayLike,
        terminated: ArrayLike,
        am: ArrayLike,
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(reward_em_base, reward_adev, reward_am_fine)`` of a step, float64 arrays of the
        steps' shape (0-d for scalars). Checks nothing.

        Args:
            dt: The step's length (s).
            em: ``info["em"]`` after the step: the misalignment at base pace (s).
            a: ``info["a"]``: the audio pace.
            motion_done: ``info["motion_done"]``.
            speech_done: ``info["speech_done"]``.
            terminated: Whether the episode ended by itself at this step.
            am: ``info["am"]`` (s); NaN where there is none (the env's None).
        """
        dt, em, a, am = (np.asarray(x, dtype=np.float64) for x in (dt, em, a, am))
        speech = np.asarray(speech_done, dtype=bool)
        going = ~(np.asarray(motion_done, dtype=bool) & speech)
        r_em = np.where(going, -self.w_em * np.abs(em) * dt, 0.0)
        r_adev = np.where(speech, 0.0, -self.w_adev * np.abs(a - 1.0) * dt)
        r_am = np.zeros(np.shape(em))
        ended = np.asarray(terminated, dtype=bool) & ~np.isnan(am)
        for i in np.flatnonzero(ended).tolist():  # math.log1p, the same in every caller
            r_am.flat[i] = -self.w_am_fine * math.log1p(abs(float(am.flat[i])) / self.am_scale)
        return r_em, r_adev, r_am
