"""The guide: progress along the trajectory, stops, and the virtual force (SPEC §1).

``F_virtual = K (x_d - x) + F_prop b (+ centripetal feed-forward on arcs)``, where ``x_d = T(s)``
is the closest point, found locally around the previous one and only inside the current stop's
window ``[previous stop, next stop]``, and ``b`` the unit tangent there.

Stops. Over the last ``brake_distance`` before a stop the propelling force tapers linearly to 0.
Past the stop the closest point is clamped to it, so the guide term ``K (T(stop) - x)`` pulls the
hand back to the end point. The stop is *reached* when ``|x - T(stop)| < stop_tol_pos`` and
``|v| < stop_tol_vel``; the window then moves on to the next segment. Motion is over when the last
stop is reached; from then on only the guide term (towards the end point) remains.

Curvature feed-forward (an addition to the paper, switch ``curvature_feedforward``). On an arc of
radius R the hand needs a centripetal force ``M0 v^2 / R``; without it the guide spring supplies it
from a lateral offset ``M0 v^2 / (R K)``, about 1.2 cm at the default parameters on the 0.368 m
arc. We add ``M0 kappa (v_par / p)^2`` (``kappa`` the curvature vector, ``v_par = v . b``); the
admittance multiplies forces by ``p^2``, so it yields exactly ``kappa v_par^2`` of acceleration at
any pace, and, scaling with ``(v / p)^2``, it keeps the time-warp property. It is not applied
while the closest point sits clamped at a stop.

``update`` and ``virtual_force`` run at 500 Hz; they work on plain floats (about 2-3 us each).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from langenv.control.admittance import AdmittanceParams
from langenv.control.trajectory import Trajectory
from langenv.errors import ConfigError

__all__ = ["Guide", "GuideState"]


@dataclass
class GuideState:
    """Progress of the guide (mutable; :meth:`copy` is cheap).

    Attributes:
        s: Arc length of the closest point (m).
        stop_index: Index into ``trajectory.stop_s`` of the next stop to reach (equal to the
            number of stops once ``done``).
        done: Whether the last stop has been reached (motion over).
    """

    s: float
    stop_index: int
    done: bool

    def copy(self) -> GuideState:
        """An independent copy."""
        return GuideState(self.s, self.stop_index, self.done)


class Guide:
    """Progress tracking and the virtual force along a trajectory.

    Args:
        trajectory: The exercise path.
        params: Stiffness, propelling force, braking and stop tolerances, mass (feed-forward).

    Raises:
        ConfigError: an argument of the wrong type.
    """

    def __init__(self, trajectory: Trajectory, params: AdmittanceParams) -> None:
        if not isinstance(trajectory, Trajectory):
            raise ConfigError(
                f"Guide: trajectory must be a Trajectory, got {type(trajectory).__name__}"
            )
        if not isinstance(params, AdmittanceParams):
            raise ConfigError(
                f"Guide: params must be AdmittanceParams, got {type(params).__name__}"
            )
        self.trajectory = trajectory
        self.params = params
        stops = [float(s) for s in trajectory.stop_s]
        self._stops = stops
        self._win_lo = [0.0, *stops[:-1]]
        self._stop_pts = [tuple(trajectory.position(s).tolist()) for s in stops]
        self._n_stops = len(stops)
        self._k = params.stiffness
        self._f_prop = params.propel_force
        self._inv_brake = 1.0 / params.brake_distance if params.brake_distance > 0 else math.inf
        self._tol_x2 = params.stop_tol_pos**2
        self._tol_v2 = params.stop_tol_vel**2
        self._ff_mass = params.mass if params.curvature_feedforward else 0.0

    @property
    def n_stops(self) -> int:
        """Number of stops (the last one is the end of the trajectory)."""
        return self._n_stops

    def initial_state(self) -> GuideState:
        """State at the start of the trajectory, before its first stop."""
        return GuideState(s=0.0, stop_index=0, done=False)

    def window(self, state: GuideState) -> tuple[float, float]:
        """Search window ``(s_lo, s_hi)`` of the current stop (m)."""
        k = min(state.stop_index, self._n_stops - 1)
        return self._win_lo[k], self._stops[k]

    def tangent(self, state: GuideState) -> np.ndarray:
        """Direction of travel ``b`` at the closest point, shape (3,).

        Unlike :meth:`Trajectory.tangent` (the right derivative), when the closest point sits
        clamped at the upcoming stop this is the tangent of the segment *arriving* there: the
        direction the hand is being guided in (a user resisting the motion pushes along ``-b``).
        Once motion is over it is the tangent at the end of the trajectory.

        Args:
            state: Guide state.

        Returns:
            Unit vector, shape (3,).
        """
        if state.done:
            seg, t = self.trajectory._local(self._stops[-1], True)
        else:
            seg, t = self.trajectory._local(state.s, state.s >= self._stops[state.stop_index])
        return np.array(seg._tangent(t))

    def update(self, state: GuideState, x: np.ndarray, v: np.ndarray) -> None:
        """Move the closest point to the hand and check whether the next stop is reached.

        Mutates ``state``: ``s`` (local closest point inside the current window), and on reaching
        the stop ``stop_index`` (and ``done`` at the last stop), with ``s`` set to the stop.

        Args:
            state: Guide state, updated in place.
            x: Hand position, shape (3,), m.
            v: Hand (reference) velocity, shape (3,), m/s.
        """
        if state.done:
            return
        k = state.stop_index
        x0, x1, x2 = x.tolist()
        s_hi = self._stops[k]
        s = self.trajectory._closest(x0, x1, x2, state.s, self._win_lo[k], s_hi)
        state.s = s
        p = self._stop_pts[k]
        d0, d1, d2 = x0 - p[0], x1 - p[1], x2 - p[2]
        if d0 * d0 + d1 * d1 + d2 * d2 < self._tol_x2:
            v0, v1, v2 = v.tolist()
            if v0 * v0 + v1 * v1 + v2 * v2 < self._tol_v2:
                state.s = s_hi
                state.stop_index = k + 1
                if k + 1 >= self._n_stops:
                    state.done = True

    def virtual_force(
        self, state: GuideState, x: np.ndarray, v: np.ndarray, p: float
    ) -> np.ndarray:
        """``F_virtual`` at the current state.

        Args:
            state: Guide state (after :meth:`update` for this tick).
            x: Hand position, shape (3,), m.
            v: Hand (reference) velocity, shape (3,), m/s.
            p: Physical pace (divides the along-path speed in the feed-forward), > 0.

        Returns:
            Force, shape (3,), N (a new array).
        """
        x0, x1, x2 = x.tolist()
        k_s = self._k
        if state.done:
            e = self._stop_pts[-1]
            return np.array((k_s * (e[0] - x0), k_s * (e[1] - x1), k_s * (e[2] - x2)))
        traj = self.trajectory
        s = state.s
        s_stop = self._stops[state.stop_index]
        rem = s_stop - s
        clamped = rem <= 0.0
        seg, t = traj._local(s, clamped)
        xd, b, kv = seg._frame(t)
        f0, f1, f2 = k_s * (xd[0] - x0), k_s * (xd[1] - x1), k_s * (xd[2] - x2)
        if clamped:
            return np.array((f0, f1, f2))
        fp = self._f_prop * (1.0 if rem * self._inv_brake >= 1.0 else rem * self._inv_brake)
        f0 += fp * b[0]
        f1 += fp * b[1]
        f2 += fp * b[2]
        if kv is not None and self._ff_mass:
            v0, v1, v2 = v.tolist()
            vp = (v0 * b[0] + v1 * b[1] + v2 * b[2]) / p
            c = self._ff_mass * vp * vp
            f0 += c * kv[0]
            f1 += c * kv[1]
            f2 += c * kv[2]
        return np.array((f0, f1, f2))
