"""What every LangCtrl policy offers: act on an observation, through the env's action space."""

from __future__ import annotations

from typing import Protocol, runtime_checkable

import numpy as np

__all__ = ["Policy"]


@runtime_checkable
class Policy(Protocol):
    """A policy of ``LangCtrl-v0``.

    A policy brings a rule, not a script: it declares the *role* of the phrase graph it speaks,
    and the exercise maps the role to a graph (:mod:`langenv.exercise.script`).

    Attributes:
        name: Short name used in tables and file names (``"lc"``, ``"ppo"``...).
        graph_role: ``"graph"``: it chooses phrases and speaks the exercise's phrase graph (or
            an override); ``"single"``: it says the exercise's one wording (AC, LC-noAP).
        decision_hz: The decision rate the policy was designed or trained for.

    A policy that must adapt to the graph it speaks (a learned model whose observation has one
    block per choice) also offers ``use_graph(spoken)``
    (:func:`langenv.exercise.script.speak` calls it before the env is built).
    """

    name: str
    graph_role: str
    decision_hz: int

    def reset(self) -> None:
        """Forget any episode state (called after ``env.reset``)."""

    def act(self, observation: np.ndarray) -> np.ndarray:
        """Action for one observation, shape ``env.action_space.shape``, float32."""
        ...
