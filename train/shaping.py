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
from typing import Any, ClassVar, Self

import numpy as np
from numpy.typing import ArrayLike

from langenv.errors import ConfigError

__all__ = ["AlignmentShaping", "ChoiceReward"]


@dataclass(frozen=True)
class _Weights:
    """Reward weights, checked where they are built: every field made a float, ``am_scale``
    finite and > 0, every other finite and >= 0 (a ConfigError naming :attr:`who` and the
    field otherwise)."""

    who: ClassVar[str] = ""
    """What the errors name (the config's wrapper)."""

    def __post_init__(self) -> None:
        for f in fields(self):
            value = getattr(self, f.name)
            scale = f.name == "am_scale"
            if not (math.isfinite(value) and (value > 0.0 if scale else value >= 0.0)):
                bound = "> 0" if scale else ">= 0"
                raise ConfigError(f"{self.who}: {f.name} must be finite and {bound}, got {value!r}")
            object.__setattr__(self, f.name, float(value))

    @classmethod
    def from_kwargs(cls, kwargs: Mapping[str, Any]) -> Self:
        """The weights of a config's keyword arguments.

        Raises:
            ConfigError: for an argument it does not take, or a bad value.
        """
        unknown = sorted(set(kwargs) - {f.name for f in fields(cls)})
        if unknown:
            raise ConfigError(f"{cls.who}: unknown argument(s) {', '.join(unknown)}")
        return cls(**kwargs)


@dataclass(frozen=True)
class AlignmentShaping(_Weights):
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

    who: ClassVar[str] = "AlignmentReward"
    w_em: float = 0.5
    w_adev: float = 0.5
    w_am_fine: float = 1.0
    am_scale: float = 0.02

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


@dataclass(frozen=True)
class ChoiceReward(_Weights):
    """The learned chooser's reward, paid once when the episode ends
    (:class:`train.choices.ChoicePoints`; the terms in its module docstring).

    Attributes:
        w_content: Weight of the content share.
        w_voice: Weight of the voice natural share.
        w_legs: Weight of the share of legs in step.
        w_am: Weight of ``|AM|`` (1/s).
        w_am_fine: Weight of ``ln(1 + |AM| / am_scale)``.
        am_scale: Scale of that term (s), > 0.
        w_am_far: Penalty when ``|AM| > 1 s``.
        w_em: Weight of the mean ``|EM|`` (1/s).
        w_stop: Penalty for a protective stop or a cut-off episode, instead of the alignment
            terms.
        w_length: Weight of the session's length (1/s).

    Raises:
        ConfigError: naming the weight, for a negative or non-finite one, or ``am_scale <= 0``.
    """

    who: ClassVar[str] = "ChoicePoints"
    w_content: float = 10.0
    w_voice: float = 5.0
    w_legs: float = 0.0
    w_am: float = 1.0
    w_am_fine: float = 0.5
    am_scale: float = 0.1
    w_am_far: float = 5.0
    w_em: float = 1.0
    w_stop: float = 10.0
    w_length: float = 0.0

    def terms(
        self,
        speech: tuple[float, float, float],
        em_mean: float,
        length: float,
        am: float | None,
    ) -> dict[str, float]:
        """The reward's terms by name: ``speech`` is (content share, voice natural share, share
        of legs in step; a NaN counts 0), ``em_mean`` the mean ``|EM|`` (s), ``length`` the
        session's (s), ``am`` the ``AM`` of an episode that ended by itself (None: a protective
        stop or a cut-off, which pays ``-w_stop``)."""
        content, voice, legs = (v if math.isfinite(v) else 0.0 for v in speech)
        terms = {
            "reward_content": self.w_content * content,
            "reward_voice": self.w_voice * voice,
            "reward_legs": self.w_legs * legs,
            "reward_em": -self.w_em * em_mean,
            "reward_length": -self.w_length * length,
        }
        if am is None:
            terms.update(reward_am=-self.w_stop, reward_am_far=0.0)
            return terms
        am = abs(am)
        terms["reward_am"] = -self.w_am * am - self.w_am_fine * math.log1p(am / self.am_scale)
        terms["reward_am_far"] = -self.w_am_far if am > 1.0 else 0.0
        return terms
