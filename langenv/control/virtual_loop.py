"""The virtual closed loop: the guided admittance, the hand moving with the velocity command.

The hand moves exactly with the command, which follows ``v_ref`` with at most
``max_acceleration`` (:func:`~langenv.control.command.follow`); after the last leg it brakes to
rest. :func:`simulate_virtual` runs it from rest at the start of a trajectory, with a given pace
and an optional external force, and returns the whole run (:class:`VirtualRun`). Tests, figures
and the motion-ETC agreement check (``bench``) use it; the env runs the same guide and admittance
on the simulated arm (:mod:`langenv.motion.tick`).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from langenv import vec
from langenv.control.admittance import AdmittanceParams, VariableAdmittance
from langenv.control.command import cap_speed, follow
from langenv.control.guide import Guide, GuideState
from langenv.control.trajectory import Trajectory
from langenv.errors import ConfigError

__all__ = ["DT", "ForceFn", "PaceFn", "VirtualRun", "simulate_virtual"]

DT = 0.002
"""Control period (s)."""

PaceFn = Callable[[float], float]
"""A physical pace as a function of time (s)."""
ForceFn = Callable[[float, np.ndarray, np.ndarray], np.ndarray]
"""An external force ``f(t, v, tangent) -> (3,)`` N (the ``User.force`` signature)."""


@dataclass(frozen=True, eq=False)
class VirtualRun:
    """Time series of a virtual closed-loop run (:func:`simulate_virtual`), one row per tick.

    Attributes:
        t: Times (s), shape (n,).
        x: Hand positions (m), shape (n, 3).
        v: Hand velocities: the velocity command (m/s), shape (n, 3).
        v_ref: The admittance's reference velocities (m/s), shape (n, 3).
        s: Closest-point arc lengths after the tick's update (m), shape (n,).
        leg: Leg being guided after the tick's update, shape (n,).
        p: Physical pace, shape (n,).
        f_ext: External force (N), shape (n, 3).
        path_error: Distance from the hand to its closest point ``|x - T(s)|`` (m), shape (n,).
        done_time: Time motion was over (the hand at rest after the last leg, s), ``None`` if
            not within the horizon.
    """

    t: np.ndarray
    x: np.ndarray
    v: np.ndarray
    v_ref: np.ndarray
    s: np.ndarray
    leg: np.ndarray
    p: np.ndarray
    f_ext: np.ndarray
    path_error: np.ndarray
    done_time: float | None

    @property
    def speed(self) -> np.ndarray:
        """Hand speed (m/s), shape (n,)."""
        return np.linalg.norm(self.v, axis=1)

    @property
    def max_speed(self) -> float:
        """Plateau (largest) hand speed (m/s)."""
        return float(self.speed.max())

    @property
    def max_path_error(self) -> float:
        """Largest distance from the path (m)."""
        return float(self.path_error.max())

    def guide_state(self, i: int) -> GuideState:
        """Guide state recorded at row ``i``."""
        n_legs = int(self.leg.max()) if self.done_time is not None else -1
        return GuideState(float(self.s[i]), int(self.leg[i]), int(self.leg[i]) == n_legs)


def simulate_virtual(
    trajectory: Trajectory,
    params: AdmittanceParams,
    p: float | PaceFn = 1.0,
    force: ForceFn | None = None,
    dt: float = DT,
    t_max: float = 60.0,
) -> VirtualRun:
    """Run the virtual closed loop from rest at the start.

    Each tick, in the controller's order: ``guide.update``; record (the state the tick starts
    from, guide state updated); after the last leg the command
    brakes towards 0 (the run ends at rest); otherwise ``F = F_virtual(p) + F_ext``, ``v_ref <-
    A(p)`` step with ``p_dot = (p(t + dt) - p(t)) / dt``, the command follows ``v_ref``; then
    ``x <- x + v_cmd dt``.

    Args:
        trajectory: The path.
        params: Virtual dynamics and guide parameters.
        p: Constant pace, or a function of time (s) returning the pace (> 0).
        force: External force ``force(t, v, tangent) -> (3,)`` N (the ``User.force`` signature,
            given the hand's velocity), or ``None`` for a fully cooperative user.
        dt: Tick (s).
        t_max: Horizon (s).

    Returns:
        The run (its last row is the tick the hand came to rest, if it did).
    """
    if not (math.isfinite(dt) and dt > 0.0):
        raise ConfigError(f"simulate_virtual: dt must be > 0, got {dt!r}")
    guide = Guide(trajectory, params)
    adm = VariableAdmittance(params)
    if callable(p):
        pace: PaceFn = p
    else:
        p_const = float(p)

        def pace(_t: float) -> float:
            return p_const

    dv_max = params.max_acceleration * dt
    state = guide.initial_state()
    x = trajectory.position(0.0)
    v = np.zeros(3)
    w = np.zeros(3)
    zero = np.zeros(3)
    rows: dict[str, list[object]] = {k: [] for k in ("t", "x", "w", "v", "s", "leg", "p", "f", "e")}
    done_time: float | None = None
    for n in range(round(t_max / dt) + 1):
        t = n * dt
        guide.update(state, x)
        pk = float(pace(t))
        for key, val in (("t", t), ("x", x.copy()), ("w", w), ("v", v), ("s", state.s)):
            rows[key].append(val)
        rows["leg"].append(state.leg)
        rows["p"].append(pk)
        rows["e"].append(vec.norm(x - trajectory.position(state.s)))
        f_ext = zero
        if state.done:
            w = follow(w, zero, dv_max)
        else:
            if force is not None:
                b = guide.tangent(state, x)
                f_ext = np.asarray(force(t, w, b), dtype=np.float64)
            p_dot = (float(pace(t + dt)) - pk) / dt
            v = adm.step(v, guide.virtual_force(state, x, v, pk) + f_ext, pk, p_dot, dt)
            target = v
            if force is not None and vec.dot(f_ext, b) > 0.0:  # pushed along: the governor
                target = cap_speed(v, guide.speed_limit(state, w))
            w = follow(w, target, dv_max)
        rows["f"].append(f_ext)
        x = x + w * dt
        if state.done and not w.any():
            done_time = t + dt
            break
    return VirtualRun(
        t=np.array(rows["t"]),
        x=np.array(rows["x"]),
        v=np.array(rows["w"]),
        v_ref=np.array(rows["v"]),
        s=np.array(rows["s"]),
        leg=np.array(rows["leg"], dtype=int),
        p=np.array(rows["p"]),
        f_ext=np.array(rows["f"]),
        path_error=np.array(rows["e"]),
        done_time=done_time,
    )
