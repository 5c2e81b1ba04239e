"""The person is you: the force of a mouse drag in MuJoCo's viewer, acting on the handle.

In MuJoCo's viewer you select a body with a double-click and drag it with Ctrl + right mouse
button: the viewer then holds a *perturbation*, a reference point that follows the mouse
(``MjvPerturb.refselpos``) for the point you grabbed (``localpos`` in the body's frame).
:class:`DragUser` turns it into the person's force: a spring from the grabbed point to the mouse,
``F = stiffness * (refselpos - grabbed point)``, at most ``max_force``, acting on the handle. The
env then measures it like any user's force (the force sensor's noise and deadband, the
cooperation filter) and the arm yields to it through the admittance. The viewer's own force
(``xfrc_applied``) is cleared, so the drag acts only through this path.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from langenv.errors import ConfigError

__all__ = ["DRAG_STIFFNESS", "MAX_DRAG_FORCE", "DragUser"]

DRAG_STIFFNESS = 300.0
"""Spring from the grabbed point to the mouse (N/m): a 10 cm drag pushes with 30 N."""

MAX_DRAG_FORCE = 60.0
"""Largest force a drag can apply (N)."""

_TRANSLATE = 1  # mujoco.mjtPertBit.mjPERT_TRANSLATE


class DragUser:
    """A user (:class:`langenv.users.User`) whose force is set from the viewer's perturbation.

    Args:
        stiffness: Spring constant (N/m), > 0.
        max_force: Force cap (N), > 0.
    """

    def __init__(
        self, stiffness: float = DRAG_STIFFNESS, max_force: float = MAX_DRAG_FORCE
    ) -> None:
        for name, value in (("stiffness", stiffness), ("max_force", max_force)):
            if not (math.isfinite(value) and value > 0.0):
                raise ConfigError(f"{name} must be finite and > 0, got {value!r}")
        self.stiffness, self.max_force = float(stiffness), float(max_force)
        self._force = np.zeros(3)

    @property
    def current(self) -> np.ndarray:
        """The force the drag applies now, shape (3,), N (a copy)."""
        return self._force.copy()

    def reset(self, rng: np.random.Generator) -> None:
        """A new session starts with no force."""
        self._force[:] = 0.0

    def force(self, t: float, hand_velocity: np.ndarray, tangent: np.ndarray) -> np.ndarray:
        """The drag's force on the handle, shape (3,), N."""
        return self._force.copy()

    def set_force(self, force: np.ndarray) -> None:
        """Set the force directly (N, shape (3,)), capped at ``max_force``."""
        f = np.asarray(force, np.float64).reshape(3)
        if not np.all(np.isfinite(f)):
            raise ConfigError(f"force must be finite, got {f}")
        norm = float(np.linalg.norm(f))
        self._force[:] = f if norm <= self.max_force else f * (self.max_force / norm)

    def update(self, perturb: Any, data: Any) -> None:
        """Read the viewer's perturbation (``MjvPerturb``) against the state ``data`` (``MjData``).

        A translation drag of a body sets the spring force; anything else (no selection, a
        rotation drag) sets zero. Clears ``data.xfrc_applied``.
        """
        data.xfrc_applied[:] = 0.0
        body = int(perturb.select)
        if body <= 0 or not int(perturb.active) & _TRANSLATE:
            self._force[:] = 0.0
            return
        grabbed = data.xpos[body] + data.xmat[body].reshape(3, 3) @ np.asarray(perturb.localpos)
        self.set_force(self.stiffness * (np.asarray(perturb.refselpos) - grabbed))
