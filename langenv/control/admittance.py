"""The paper's variable admittance ``A(p)`` (SPEC §1, paper §III-D).

The virtual dynamics turn the total force on the handle into the reference velocity::

    M0 dv/dt = p^2 F - (p D0 - (dp/dt / p) M0) v,        F = F_ext + F_virtual,

which, for a fixed force, plays the ``p = 1`` solution ``v*`` back in warped time:
``v(t) = p(t) v*(Phi(t))`` with ``Phi = integral of p``.

Integrator. With ``w = v / p`` the equation becomes ``dw/dt = p (F - D0 w) / M0``, i.e.
``dw/dPhi = (F - D0 w) / M0``: the plain ``p = 1`` admittance in warped time. One step holds ``F``
and ``dp/dt`` over ``dt`` (so ``p`` is linear over the step, ending at ``p + p_dot dt``), advances
``Phi`` by ``p dt + p_dot dt^2 / 2`` and updates ``w`` by the exact exponential of the linear ODE.
The step is therefore exact for piecewise-constant forces and piecewise-linear paces, stable for
any ``dt`` (the decay factor ``exp(-D0 dPhi / M0)`` lies in (0, 1]), and keeps the time-warp
property up to the quadrature of ``Phi``. It works on plain floats: one call costs about 1 us.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields

import numpy as np

from langenv.errors import ConfigError
from langenv.layout import field_table

__all__ = ["ADMITTANCE_SETTINGS", "ADMITTANCE_STATE", "AdmittanceParams", "VariableAdmittance"]

ADMITTANCE_STATE = field_table(
    """
    v_ref[3]  the reference velocity (m/s)
    """
)
"""The admittance's state: the velocity :meth:`VariableAdmittance.step` integrates."""
ADMITTANCE_SETTINGS = field_table(
    """
    d_over_m  D0 / M0 (1/s)
    inv_d     1 / D0 (s m / N)
    """
)
"""The admittance's settings (:meth:`VariableAdmittance.settings`)."""


@dataclass(frozen=True)
class AdmittanceParams:
    """Virtual dynamics and guide parameters (SPEC §2 defaults).

    Args:
        mass: Virtual mass ``M0`` (kg), > 0.
        damping: Virtual damping ``D0`` (N s/m), > 0.
        stiffness: Guide stiffness ``K`` (N/m), > 0.
        propel_force: Propelling force ``|F_prop|`` (N), >= 0; the guided hand settles at
            ``propel_force / damping`` (0.125 m/s).
        switch_tol: The guide moves on to the next leg when the hand's pose is this close to the
            leg's end pose, in the lab code's 6-D norm ``sqrt(|dx|^2 + dphi^2)`` (m and rad of
            tool rotation), > 0. The lab's 0.1 is about 3.5 cm before the end on the default
            exercise.
        max_acceleration: Acceleration limit of the velocity command sent to the robot (m/s^2,
            the ``a`` of a UR's ``speedL``), > 0: the hand follows ``v_ref`` changing its
            velocity at most this fast, and brakes to rest at this rate when motion ends.
            ``math.inf``: the hand tracks ``v_ref`` exactly.
        curvature_feedforward: Add the centripetal term ``M0 kappa (v_par / p)^2`` on curved
            segments (an addition to the paper; it keeps the hand on arcs).

    The bounds of the physical pace are not here: they are the env's
    :class:`~langenv.control.pacing.PaceLimits`, their one source; the admittance accepts any
    pace > 0.

    Raises:
        ConfigError: a field out of range or non-finite (names the field).
    """

    mass: float = 40.0
    damping: float = 80.0
    stiffness: float = 120.0
    propel_force: float = 10.0
    switch_tol: float = 0.1
    max_acceleration: float = 0.14
    curvature_feedforward: bool = True

    def __post_init__(self) -> None:
        for f in fields(self):
            if f.name == "curvature_feedforward":
                continue
            value = getattr(self, f.name)
            if isinstance(value, bool) or not isinstance(value, int | float):
                raise ConfigError(
                    f"AdmittanceParams.{f.name} must be a number, got {type(value).__name__}"
                )
            if not math.isfinite(value) and not (f.name == "max_acceleration" and value > 0):
                raise ConfigError(f"AdmittanceParams.{f.name} must be finite, got {value!r}")
            object.__setattr__(self, f.name, float(value))
        positive = ("mass", "damping", "stiffness", "switch_tol", "max_acceleration")
        for name in positive:
            if getattr(self, name) <= 0.0:
                raise ConfigError(f"AdmittanceParams.{name} must be > 0, got {getattr(self, name)}")
        if self.propel_force < 0.0:
            raise ConfigError(
                f"AdmittanceParams.propel_force must be >= 0, got {self.propel_force}"
            )
        if not isinstance(self.curvature_feedforward, bool):
            raise ConfigError(
                "AdmittanceParams.curvature_feedforward must be a bool, got "
                f"{type(self.curvature_feedforward).__name__}"
            )

    @property
    def plateau_speed(self) -> float:
        """Speed the propelling force alone settles the hand at, ``F_prop / D0`` (m/s)."""
        return self.propel_force / self.damping


class VariableAdmittance:
    """The paper's ``A(p)``: reference velocity from force, pace and pace rate.

    Args:
        params: Mass and damping are read from here.

    Raises:
        ConfigError: ``params`` is not an :class:`AdmittanceParams`.
    """

    def __init__(self, params: AdmittanceParams) -> None:
        if not isinstance(params, AdmittanceParams):
            raise ConfigError(
                f"VariableAdmittance: params must be AdmittanceParams, got {type(params).__name__}"
            )
        self.params = params
        self._m = params.mass
        self._d_over_m = params.damping / params.mass
        self._inv_d = 1.0 / params.damping

    def settings(self) -> dict[str, float]:
        """The settings by the names of :data:`ADMITTANCE_SETTINGS`."""
        return {"d_over_m": self._d_over_m, "inv_d": self._inv_d}

    def step(
        self, v: np.ndarray, force: np.ndarray, p: float, p_dot: float, dt: float
    ) -> np.ndarray:
        """Advance ``M0 dv/dt = p^2 F - (p D0 - (p_dot / p) M0) v`` by one step.

        ``force`` and ``p_dot`` are held over the step, so ``p`` moves linearly from ``p`` to
        ``p + p_dot dt`` (see the module docstring for the exact update).

        Args:
            v: Reference velocity at the start of the step, shape (3,), m/s.
            force: Total force ``F_ext + F_virtual``, shape (3,), N.
            p: Physical pace at the start of the step, > 0 (the env keeps it within its
                :class:`~langenv.control.pacing.PaceLimits`).
            p_dot: Its rate (1/s), finite; ``p + p_dot dt`` must stay > 0.
            dt: Step (s), > 0.

        Returns:
            Reference velocity at the end of the step, shape (3,), m/s (a new array).

        Raises:
            ConfigError: ``p`` not > 0 or not finite, a non-finite ``v``, ``force`` or
                ``p_dot``, or a non-positive ``dt`` (names the argument).
        """
        if not 0.0 < p < math.inf:
            raise ConfigError(f"VariableAdmittance.step: p must be finite and > 0, got {p!r}")
        if not dt > 0.0 or not math.isfinite(dt):
            raise ConfigError(f"VariableAdmittance.step: dt must be > 0 and finite, got {dt!r}")
        if not math.isfinite(p_dot):
            raise ConfigError(f"VariableAdmittance.step: p_dot must be finite, got {p_dot!r}")
        p_end = p + p_dot * dt
        if not p_end > 0.0:
            raise ConfigError(
                f"VariableAdmittance.step: p_dot={p_dot!r} drives p to {p_end!r} <= 0 within dt"
            )
        f0, f1, f2 = force.tolist()
        v0, v1, v2 = v.tolist()
        if not math.isfinite(f0 + f1 + f2):
            raise ConfigError(f"VariableAdmittance.step: force must be finite, got {force!r}")
        if not math.isfinite(v0 + v1 + v2):
            raise ConfigError(f"VariableAdmittance.step: v must be finite, got {v!r}")
        # w = v / p obeys dw/dPhi = (F - D0 w) / M0; exact over dPhi with F held.
        decay = math.exp(-self._d_over_m * (p + 0.5 * p_dot * dt) * dt)
        inv_d, inv_p = self._inv_d, 1.0 / p
        a0, a1, a2 = f0 * inv_d, f1 * inv_d, f2 * inv_d  # w_inf = F / D0
        return np.array(
            (
                p_end * (a0 + (v0 * inv_p - a0) * decay),
                p_end * (a1 + (v1 * inv_p - a1) * decay),
                p_end * (a2 + (v2 * inv_p - a2) * decay),
            )
        )
