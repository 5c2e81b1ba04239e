"""What every LangCtrl policy offers: act on an observation, through the env's action space."""

from __future__ import annotations

from typing import Protocol, runtime_checkable

import numpy as np

__all__ = ["Policy"]


@runtime_checkable
class Policy(Protocol):
    """A policy of ``LangCtrl-v0``.

    Attributes:
        name: Short name used in tables and file names (``"lc"``, ``"ppo"``...).
        phrase_graph: The phrase graph the policy speaks with: a shipped graph key (``"lc"``,
            ``"lc-noap"``, ``"ac"``) or a YAML path, passed to the env as ``phrase_graph``.
        decision_hz: The decision rate the policy was designed or trained for.
    """

    name: str
    phrase_graph: str
    decision_hz: int

    def reset(self) -> None:
        """Forget any episode state (called after ``env.reset``)."""

    def act(self, observation: np.ndarray) -> np.ndarray:
        """Action for one observation, shape ``env.action_space.shape``, float32."""
        ...
