"""Motion time-to-completion ``t_x`` (SPEC §1): the paper's reference and a fast estimator.

``t_x`` is the time the virtual closed loop needs to finish the whole trajectory from the current
state, assuming a fully cooperative user (``F_ext = 0``) at base pace (``p = 1``).

* :func:`reference_etc` is the paper's definition: simulate the loop at 500 Hz (guide, leg
  switching, admittance and the acceleration-limited velocity command exactly as the controller
  runs them, the hand following the command) until motion is over: the last leg done and the
  hand braked to rest.
* :class:`FastETC` answers the same question in a few microseconds. With the curvature
  feed-forward on, the motion along the path obeys a one-dimensional law on every leg: with ``q``
  the distance left to the leg's end, ``u`` the admittance's velocity ``v_ref`` and ``w`` the
  hand's (command) velocity along the path, ``M0 du/dt = F_prop - D0 u`` on the leg
  (``F_prop + K (q - L) - D0 u`` behind its start, ``L`` the leg's length), ``w`` follows ``u``
  changing at most at ``a`` (``max_acceleration``) and ``dq/dt = -w``. The guide moves on when
  ``q`` falls below the leg's switch distance
  (:meth:`~langenv.control.guide.Guide.switch_distance`), whatever the speed, so on the leg the
  time to the switch has a closed form: a ramp of ``w`` at ``a`` until it meets ``u`` (one root),
  then the exponential of the admittance (a few Newton steps). Behind the start the law is
  tabulated once. The rest of the exercise after a switch depends only on ``(u, w)`` then (the
  hand starts the next leg a little in, moving backwards): it is tabulated per leg by simulating
  the 1-D law of the next legs (vectorised), chained backwards from the last, whose rest is the
  braking time ``|w| / a``. A query costs one projection, one closed form and one interpolation.

FastETC builds its tables and answers its queries in compiled code,
:mod:`langenv.control.motion_etc_kernels`; the query's Python reference is here, under the same
names on the same packed arrays (:func:`estimate_parts`, :func:`finish_parts`, :func:`finish`,
:func:`to_switch`, :func:`ramp_end`, :func:`table2`, :func:`nominal_rest`), and the tests hold
the twin to it (``tests/test_law_homes.py``).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from langenv.control import etc_cache
from langenv.control import motion_etc_kernels as etc_kernel
from langenv.control.admittance import VariableAdmittance
from langenv.control.command import follow
from langenv.control.guide import Guide, GuideState
from langenv.control.motion_etc_kernels import ETC_LEG, ETC_PARAMS
from langenv.control.motion_etc_kernels import simulate as simulate_law
from langenv.control.trajectory import Trajectory
from langenv.errors import ConfigError

__all__ = [
    "DT",
    "FastETC",
    "estimate_parts",
    "finish",
    "finish_parts",
    "nominal_rest",
    "ramp_end",
    "reference_etc",
    "table2",
    "to_switch",
]

DT = 0.002
"""Control period (s)."""


def reference_etc(
    guide: Guide,
    admittance: VariableAdmittance,
    state: GuideState,
    x: np.ndarray,
    v_ref: np.ndarray,
    v_cmd: np.ndarray | None = None,
    dt: float = DT,
    t_max: float = 120.0,
) -> float:
    """Time to complete the trajectory by simulating the virtual closed loop (the paper's ``t_x``).

    Each tick, as the controller runs it: ``guide.update``; after the last leg the command brakes
    towards 0 and the run ends when it gets there; otherwise ``v_ref <- A(1)(F_virtual)``
    (``F_ext = 0``, ``p = 1``), the command follows ``v_ref``
    (:func:`~langenv.control.command.follow`) and ``x <- x + v_cmd dt`` (the hand moves with the
    command). The result counts the ticks.

    Args:
        guide: The guide (trajectory, legs, virtual force).
        admittance: The admittance (its parameters, ``max_acceleration`` included).
        state: Current guide state (not modified; a copy is simulated).
        x: Hand position, shape (3,), m.
        v_ref: The admittance's reference velocity, shape (3,), m/s.
        v_cmd: The velocity command (the hand's velocity), shape (3,), m/s; ``None``: ``v_ref``.
        dt: Tick (s).
        t_max: Give up after this simulated time (s).

    Returns:
        Time to completion (s); ``math.inf`` if motion is not over within ``t_max``.
    """
    st = state.copy()
    x = np.array(x, dtype=np.float64)
    v = np.array(v_ref, dtype=np.float64)
    w = v.copy() if v_cmd is None else np.array(v_cmd, dtype=np.float64)
    dv_max = admittance.params.max_acceleration * dt
    zero = np.zeros(3)
    update, force, step = guide.update, guide.virtual_force, admittance.step
    for n in range(int(t_max / dt) + 1):
        update(st, x)
        if st.done:
            if not w.any():
                return n * dt
            w = follow(w, zero, dv_max)
            if not w.any():
                return (n + 1) * dt
        else:
            v = step(v, force(st, x, v, 1.0), 1.0, 0.0, dt)
            w = follow(w, v, dv_max)  # no push along: the speed governor does nothing
        x += w * dt
    return math.inf


def _leg_states(
    q: np.ndarray,
    u: np.ndarray,
    w: np.ndarray,
    lateral: tuple[np.ndarray, np.ndarray, np.ndarray] | None,
) -> tuple[np.ndarray, ...]:
    """``(q, u, w, y, ul, wl)`` as flat float64 copies (zero lateral state without ``lateral``)."""
    q, u, w = (np.array(a, dtype=np.float64).ravel() for a in (q, u, w))
    if lateral is None:
        return q, u, w, np.zeros(q.size), np.zeros(q.size), np.zeros(q.size)
    y, ul, wl = (np.array(a, dtype=np.float64).ravel() for a in lateral)
    return q, u, w, y, ul, wl


class _Law:
    """The 1-D along-path law of a leg (module docstring): admittance, command ramp, position."""

    def __init__(self, admittance: VariableAdmittance, dt: float) -> None:
        params = admittance.params
        self.dt = dt
        self.decay = math.exp(-params.damping / params.mass * dt)
        self.inv_d = 1.0 / params.damping
        self.f_prop = params.propel_force
        self.k = params.stiffness
        self.acc = params.max_acceleration
        self.u_inf = params.propel_force / params.damping
        self.tau = params.mass / params.damping
        e = self.decay
        self.tau_d = dt * e / (1.0 - e)  # displacement factor of the discrete law (~ tau - dt/2)

    def simulate(
        self,
        q: np.ndarray,
        u: np.ndarray,
        w: np.ndarray,
        length: float,
        q_sw: float,
        lateral: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None,
        t_max: float = 60.0,
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """:meth:`simulate_numpy`, compiled
        (:func:`langenv.control.motion_etc_kernels.simulate`): the same results."""
        q, u, w, y, ul, wl = _leg_states(q, u, w, lateral)
        out = np.empty((4, q.size))
        gain = (1.0 - self.decay) * self.inv_d
        n_ticks = int(t_max / self.dt) + 1
        simulate_law(
            q, u, w, y, ul, wl, length, q_sw, self.f_prop, self.k, self.decay, gain,
            self.acc * self.dt, self.dt, n_ticks, out,
        )  # fmt: skip
        return out[0], out[1], out[2], out[3]

    def simulate_numpy(
        self,
        q: np.ndarray,
        u: np.ndarray,
        w: np.ndarray,
        length: float,
        q_sw: float,
        lateral: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None,
        t_max: float = 60.0,
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Vectorised discrete law on one leg from states ``(q, u, w)`` until each switches.

        The same update as :func:`reference_etc` in the leg's frame: along it, force ``F_prop``
        on the leg and ``F_prop + K (q - length)`` behind its start; across it (``lateral``:
        offset ``y``, ``v_ref`` and command components, for the turn just after a switch) the
        spring ``-K y``. The command moves towards ``v_ref`` by at most ``a dt`` (the two
        components share that budget, as in 3-D); ``q -= w dt``. A state switches once
        ``q < q_sw`` (checked before the tick, as the guide does).

        Returns:
            ``(time, q, u, w)`` at the switch, flat arrays; for a state that has not switched
            within ``t_max``, ``inf`` time and its ``q, u, w`` then.
        """
        q, u, w, y, ul, wl = _leg_states(q, u, w, lateral)
        t_out = np.full(q.size, np.inf)
        q_out, u_out, w_out = q.copy(), u.copy(), w.copy()
        idx = np.arange(q.size)
        gain = (1.0 - self.decay) * self.inv_d
        dw = self.acc * self.dt
        for n in range(int(t_max / self.dt) + 1):
            hit = q < q_sw
            if hit.any():
                where = idx[hit]
                t_out[where], q_out[where] = n * self.dt, q[hit]
                u_out[where], w_out[where] = u[hit], w[hit]
                keep = ~hit
                q, u, w, idx = q[keep], u[keep], w[keep], idx[keep]
                y, ul, wl = y[keep], ul[keep], wl[keep]
                if idx.size == 0:
                    break
            f = self.f_prop + self.k * np.maximum(q - length, 0.0)
            u = u * self.decay + f * gain
            ul = ul * self.decay - (self.k * gain) * y
            du, dl = u - w, ul - wl
            norm = np.sqrt(du * du + dl * dl)
            scale = np.where(norm > dw, dw / np.maximum(norm, 1e-300), 1.0)
            w = w + du * scale
            wl = wl + dl * scale
            q = q - w * self.dt
            y = y + wl * self.dt
        q_out[idx], u_out[idx], w_out[idx] = q, u, w
        return t_out, q_out, u_out, w_out


_TURN_TIME = 1.5
"""Time (s) after a switch simulated in the rest tables: the turn into the next leg (the
lateral motion and the command's lag die out); the rest of the leg is the closed form."""

_TABLES: dict[tuple[object, ...], Any] = {}
"""FastETC's tables by trajectory geometry, parameters and table settings (built once)."""


class FastETC:
    """Fast estimate of :func:`reference_etc` (a few microseconds per call).

    See the module docstring for the 1-D law and the tables.

    Args:
        guide: The guide (its trajectory and parameters define the legs).
        admittance: The admittance (its parameters define the law).
        dt: Tick of the reference simulation (s).
        u_range: Speeds covered by the tables (m/s); queries outside are clamped.
        u_step: Speed step of the tables (m/s).
        overshoot: Largest distance behind a leg's start covered (m).
        q_step: Distance step of the behind-the-start table (m).
        behind_u_step: Speed step of the behind-the-start table (m/s).

    Raises:
        ConfigError: ``propel_force == 0`` (the hand would never finish) or a bad table setting.
    """

    def __init__(
        self,
        guide: Guide,
        admittance: VariableAdmittance,
        *,
        dt: float = DT,
        u_range: tuple[float, float] = (-0.3, 0.5),
        u_step: float = 0.01,
        overshoot: float = 0.1,
        q_step: float = 0.005,
        behind_u_step: float = 0.02,
    ) -> None:
        if guide.params.propel_force <= 0.0:
            raise ConfigError("FastETC: AdmittanceParams.propel_force must be > 0")
        checks = (
            ("dt", dt),
            ("u_step", u_step),
            ("overshoot", overshoot),
            ("q_step", q_step),
            ("behind_u_step", behind_u_step),
        )
        for name, val in checks:
            if not (math.isfinite(val) and val > 0.0):
                raise ConfigError(f"FastETC: {name} must be > 0, got {val!r}")
        if not u_range[0] < 0.0 < u_range[1]:
            raise ConfigError(f"FastETC: u_range must contain 0, got {u_range!r}")
        self.guide = guide
        self.admittance = admittance
        self.dt = dt
        law = self._law = _Law(admittance, dt)
        traj = guide.trajectory
        self._traj = traj
        ends = [float(s) for s in traj.waypoint_s]
        self._ends = ends
        self._n_legs = len(ends)
        self._lengths = [b - a for a, b in zip([0.0, *ends[:-1]], ends, strict=True)]
        self._q_sw = [guide.switch_distance(k) for k in range(len(ends))]
        self._cos: list[float] = []  # tangents arriving at / leaving the end of each leg
        for s in ends[:-1]:
            # the segment ending the leg and the next one, by index: the next segment's start
            # arc length (an end minus a length) may differ from this end by a rounding error,
            # which would make ``locate(s)`` return the arriving segment for both
            i = traj.segment_index(s, "left")
            seg_in, seg_out = traj.segments[i], traj.segments[i + 1]
            b_in, b_out = seg_in.unit_tangent(seg_in.length), seg_out.unit_tangent(0.0)
            self._cos.append(sum(a * b for a, b in zip(b_in, b_out, strict=True)))
        self._inv_acc = 1.0 / law.acc
        n_u = math.ceil((u_range[1] - u_range[0]) / u_step) + 1
        self._u0, self._du, self._nu = float(u_range[0]), float(u_step), n_u
        key = (  # everything the tables depend on, derived values included (etc_cache's key)
            traj.fingerprint(),
            admittance.params,
            guide.params,
            tuple(self._lengths),
            tuple(self._q_sw),
            tuple(self._cos),
            dt,
            u_range,
            u_step,
            overshoot,
            q_step,
            behind_u_step,
        )
        self.path: np.ndarray = traj.packed()
        """The trajectory packed for the compiled kernels (:meth:`Trajectory.packed
        <langenv.control.trajectory.Trajectory.packed>`)."""
        tables = _TABLES.get(key)
        if tables is None:  # built once per machine (etc_cache), then once per process at most
            tables = etc_cache.load_tables(key)
            if tables is None:
                tables = self._build(u_step, overshoot, q_step, behind_u_step)
                etc_cache.store_tables(key, *tables)
            _TABLES[key] = tables
        self.prm: np.ndarray = tables[0]
        """The law, the table grids and the legs, packed for
        :func:`langenv.control.motion_etc_kernels.estimate_parts` (read-only)."""
        self.tab: np.ndarray = tables[1]
        """The tables, flat (read-only)."""

    def _params(
        self,
        behind_shape: tuple[int, int, int],
        origin: tuple[float, ...],
        steps: tuple[float, ...],
    ) -> np.ndarray:
        """``prm`` of :mod:`langenv.control.motion_etc_kernels`: :data:`ETC_PARAMS`, then a row of
        :data:`ETC_LEG` per leg."""
        law = self._law
        size = behind_shape[0] * behind_shape[1] * behind_shape[2]
        prm = np.zeros(ETC_PARAMS.size + ETC_LEG.size * self._n_legs)
        ETC_PARAMS.pack_all(
            prm,
            {
                "dt": law.dt, "acc": law.acc, "u_inf": law.u_inf, "tau": law.tau,
                "tau_d": law.tau_d, "inv_acc": self._inv_acc, "behind_origin": origin,
                "behind_step": steps, "behind_shape": behind_shape, "rest_u0": self._u0,
                "rest_du": self._du, "rest_n": self._nu, "n_legs": self._n_legs,
                "rest_offset": 3 * self._n_legs * size,
            },
        )  # fmt: skip
        for k in range(self._n_legs):
            row = prm[ETC_PARAMS.size + ETC_LEG.size * k :]
            ETC_LEG.pack_all(
                row, {"end": self._ends[k], "length": self._lengths[k], "switch": self._q_sw[k]}
            )
        return prm

    def _build(
        self, u_step: float, overshoot: float, q_step: float, behind_u_step: float
    ) -> tuple[np.ndarray, np.ndarray]:
        """The packed law and tables (cached per geometry and params): behind each leg's start,
        and the rest of the exercise after each switch."""
        law = self._law
        ug = self._u0 + self._du * np.arange(self._nu)
        # behind a leg's start (pushed back past it): time and (u, w) when back on it
        n_q = math.ceil(overshoot / q_step) + 1
        n_b = math.ceil((ug[-1] - ug[0]) / behind_u_step) + 1
        ub = self._u0 + behind_u_step * np.arange(n_b)
        ee, bu, bw = np.meshgrid(q_step * np.arange(n_q), ub, ub, indexing="ij")
        prm = self._params(
            (n_q, n_b, n_b), (0.0, self._u0, self._u0), (q_step, behind_u_step, behind_u_step)
        )
        behind = []
        for length in self._lengths:
            back = law.simulate(length + ee.ravel(), bu.ravel(), bw.ravel(), length, length)
            t_b = np.where(np.isfinite(back[0]), back[0], 60.0)
            behind += [t_b, back[2], back[3]]
        # rest of the exercise after the switch at the end of leg k, over (u, w) then: the turn
        # into leg k + 1 simulated (with its lateral part), then the closed form of that leg
        n_u = self._nu
        rest = np.zeros((self._n_legs, n_u, n_u))
        rest[-1] = np.abs(ug)[None, :] * self._inv_acc  # the last leg: braking to rest
        tab = np.concatenate([*behind, rest.ravel()])
        uu, ww = np.meshgrid(ug, ug, indexing="ij")
        r0 = int(prm[ETC_PARAMS.at.rest_offset])
        for k in range(self._n_legs - 2, -1, -1):
            c, j = self._cos[k], k + 1
            sn = math.sqrt(max(1.0 - c * c, 0.0))
            q_next = self._lengths[j] + self._q_sw[k] * c
            lateral = (np.full(uu.size, -self._q_sw[k] * sn), uu.ravel() * sn, ww.ravel() * sn)
            t1, q1, u1, w1 = law.simulate(
                np.full(uu.size, q_next),
                uu.ravel() * c,
                ww.ravel() * c,
                self._lengths[j],
                self._q_sw[j],
                lateral,
                t_max=_TURN_TIME,
            )
            t_turn = (int(_TURN_TIME / self.dt) + 1) * self.dt  # the ticks simulate() ran
            off_j = r0 + j * n_u * n_u
            values = [
                t + etc_kernel.table2(tab, off_j, self._u0, self._du, n_u, u, w)
                if t < math.inf
                else t_turn + etc_kernel.finish(prm, tab, j, q, u, w)
                for t, q, u, w in zip(
                    t1.tolist(), q1.tolist(), u1.tolist(), w1.tolist(), strict=True
                )
            ]
            tab[r0 + k * n_u * n_u : r0 + (k + 1) * n_u * n_u] = values
        prm.setflags(write=False)
        tab.setflags(write=False)
        return prm, tab

    # --- evaluation -------------------------------------------------------------------------
    def _finish(self, k: int, q: float, u: float, w: float) -> float:
        """Time to finish the exercise from the 1-D state ``(q, u, w)`` on leg ``k``."""
        return float(etc_kernel.finish(self.prm, self.tab, k, q, u, w))

    def along_path(
        self, state: GuideState, x: np.ndarray, v_ref: np.ndarray, v_cmd: np.ndarray
    ) -> tuple[float, float, float]:
        """The 1-D state: distance left to the leg's end and the two speeds along the path.

        Args:
            state: Guide state.
            x: Hand position, shape (3,), m.
            v_ref: The admittance's reference velocity, shape (3,), m/s.
            v_cmd: The velocity command (the hand's), shape (3,), m/s.

        Returns:
            ``(q, u, w)``: ``q`` (m) is negative past the leg's end and larger than the leg's
            length behind its start; ``u``, ``w`` (m/s) are negative when moving backwards.
        """
        return _along(self._traj, self._ends[state.leg], state.s, x.tolist(), v_ref.tolist(),
                      v_cmd.tolist())  # fmt: skip

    def etc(
        self,
        state: GuideState,
        x: np.ndarray,
        v_ref: np.ndarray,
        v_cmd: np.ndarray | None = None,
    ) -> float:
        """Estimated time to complete the trajectory from the current state (s).

        Args:
            state: Guide state (``s`` may lag the hand by a tick: the projection corrects it).
            x: Hand position, shape (3,), m.
            v_ref: The admittance's reference velocity, shape (3,), m/s.
            v_cmd: The velocity command (the hand's), shape (3,), m/s; ``None``: ``v_ref``.

        Returns:
            Time (s); after the last leg the braking time left, ``0.0`` once at rest.
        """
        t_leg, rest = self.times(state, x, v_ref, v_cmd)
        return t_leg + rest

    def times(
        self,
        state: GuideState,
        x: np.ndarray,
        v_ref: np.ndarray,
        v_cmd: np.ndarray | None = None,
    ) -> tuple[float, float]:
        """:meth:`etc` in two parts (their sum): the time to the current leg's switch (once
        done: the braking time) and the rest of the exercise after it (0 once done) (s)."""
        w_vec = v_ref if v_cmd is None else v_cmd
        x0, x1, x2 = x.tolist()
        v0, v1, v2 = v_ref.tolist()
        c0, c1, c2 = w_vec.tolist()
        t_leg, rest = etc_kernel.estimate_parts(
            self.prm,
            self.tab,
            self.path,
            state.leg,
            state.s,
            state.done,
            (x0, x1, x2),
            (v0, v1, v2),
            (c0, c1, c2),
        )
        return float(t_leg), float(rest)

    def nominal_rest(self, leg: int) -> float:
        """The rest of the exercise after leg ``leg``'s switch at the guided plateau speed (s):
        what :class:`~langenv.speech.legs.LegPlan` counts after a segment's last leg."""
        return float(etc_kernel.nominal_rest(self.prm, self.tab, leg))

    def nominal(self) -> float:
        """Estimated time of the whole exercise from rest at the start (s)."""
        return self._finish(0, self._lengths[0], 0.0, 0.0)


# --- the query in Python: the reference of motion_etc_kernels' estimate_parts ------------------
_P = ETC_PARAMS.at
_L = ETC_LEG.at
_LEG0 = ETC_PARAMS.size
_NL = ETC_LEG.size


def _along(
    traj: Trajectory, s_end: float, s: float, x: list[float], v: list[float], c: list[float]
) -> tuple[float, float, float]:
    """``(q, u, w)``: the hand's distance left to ``s_end`` and the two speeds along the path."""
    seg, t = traj.locate(s, s >= s_end)
    xd, b, _ = seg.frame(t)
    q = s_end - s - ((x[0] - xd[0]) * b[0] + (x[1] - xd[1]) * b[1] + (x[2] - xd[2]) * b[2])
    return q, v[0] * b[0] + v[1] * b[1] + v[2] * b[2], c[0] * b[0] + c[1] * b[1] + c[2] * b[2]


def table2(tab: np.ndarray, off: int, x0: float, dx: float, n: int, x: float, y: float) -> float:
    """Bilinear lookup in the ``n`` x ``n`` table at ``tab[off:]`` (grid ``x0 + dx i`` on both
    axes), clamped at its edges."""
    fi = (x - x0) / dx
    fj = (y - x0) / dx
    hi = n - 1.000001
    fi = 0.0 if fi < 0.0 else (hi if fi > hi else fi)
    fj = 0.0 if fj < 0.0 else (hi if fj > hi else fj)
    i, k = int(fi), int(fj)
    a, b = fi - i, fj - k
    r0 = off + i * n
    r1 = r0 + n
    t00, t01, t10, t11 = (float(tab[j]) for j in (r0 + k, r0 + k + 1, r1 + k, r1 + k + 1))
    return (1.0 - a) * (t00 + b * (t01 - t00)) + a * (t10 + b * (t11 - t10))


def _table3(tab: np.ndarray, off: int, prm: np.ndarray, x: float, y: float, z: float) -> float:
    """Trilinear lookup in a behind-the-start table, clamped at its edges."""
    shape = [int(prm[_P.behind_shape + d]) for d in range(3)]
    f = [
        min(max((v - float(prm[_P.behind_origin + d])) / float(prm[_P.behind_step + d]), 0.0),
            shape[d] - 1.000001)
        for d, v in enumerate((x, y, z))
    ]  # fmt: skip
    i, j, k = int(f[0]), int(f[1]), int(f[2])
    a, b, c = f[0] - i, f[1] - j, f[2] - k
    ny, nz = shape[1], shape[2]
    base = off + (i * ny + j) * nz + k
    out = 0.0
    for di in range(2):
        wa = 1.0 - a if di == 0 else a
        for dj in range(2):
            wb = 1.0 - b if dj == 0 else b
            n = base + di * ny * nz + dj * nz
            t0, t1 = float(tab[n]), float(tab[n + 1])
            out += wa * wb * (t0 + c * (t1 - t0))
    return out


def ramp_end(prm: np.ndarray, u0: float, w0: float) -> tuple[float, float]:
    """When the command ``w`` (from ``w0``, changing at the acceleration limit) catches up with
    ``v_ref`` (from ``u0``, relaxing to the plateau): ``(time, direction)``; a bisection to
    1 us."""
    ui, tau, acc = float(prm[_P.u_inf]), float(prm[_P.tau]), float(prm[_P.acc])

    def g(t: float, s: float) -> float:
        return s * (ui + (u0 - ui) * math.exp(-t / tau) - w0) - acc * t

    gap = u0 - w0
    slope0 = (ui - u0) / tau
    if acc == math.inf or (-1e-12 < gap < 1e-12 and -acc <= slope0 <= acc):
        return 0.0, 0.0
    if abs(gap) >= 1e-12:
        s = 1.0 if gap > 0.0 else -1.0
    else:
        s = 1.0 if slope0 > 0 else -1.0
    hi = (abs(ui - w0) + abs(u0 - ui)) / acc + tau
    lo = 0.0
    if g(0.0, s) <= 0.0:
        lo = (tau if tau < hi else hi) * 1e-3
        while g(lo, s) <= 0.0 and lo < hi:
            lo *= 2.0
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        if g(mid, s) > 0.0:
            lo = mid
        else:
            hi = mid
        if hi - lo < 1e-6:
            break
    return hi, s


def _time_to_cover(prm: np.ndarray, dist: float, u0: float) -> float:
    """Time for the admittance's exponential from ``u0`` to cover ``dist`` (Newton)."""
    if dist <= 0.0:
        return 0.0
    ui, tau = float(prm[_P.u_inf]), float(prm[_P.tau])
    a = (u0 - ui) * float(prm[_P.tau_d])
    t = max((dist - a) / ui, 0.0)
    for _ in range(30):
        ex = math.exp(-t / tau)
        g = ui * t + a * (1.0 - ex) - dist
        dg = ui + a / tau * ex
        if dg <= 0.0:
            dg = ui
        step = g / dg
        t = max(t - step, 0.0)
        if -1e-7 < step < 1e-7:
            break
    return t


def to_switch(prm: np.ndarray, dist: float, u0: float, w0: float) -> tuple[float, float, float]:
    """Time for a leg's motion from ``(u0, w0)`` to cover ``dist`` and ``(u, w)`` then."""
    ui, tau, acc = float(prm[_P.u_inf]), float(prm[_P.tau]), float(prm[_P.acc])
    t_c, s = ramp_end(prm, u0, w0)
    if t_c > 0.0:
        reach = w0 * t_c + 0.5 * s * acc * t_c * t_c
        if reach >= dist:  # the switch comes during the ramp
            root = math.sqrt(max(w0 * w0 + 2.0 * s * acc * dist, 0.0))
            t = (-w0 + root) / acc if s > 0 else (w0 - root) / acc
            return t, ui + (u0 - ui) * math.exp(-t / tau), w0 + s * acc * t
        u0 = ui + (u0 - ui) * math.exp(-t_c / tau)
        dist -= reach
    t = _time_to_cover(prm, dist, u0)
    u = ui + (u0 - ui) * math.exp(-t / tau)
    return t_c + t, u, u


def finish_parts(
    prm: np.ndarray, tab: np.ndarray, k: int, q: float, u: float, w: float
) -> tuple[float, float]:
    """The time to finish the exercise from the 1-D state ``(q, u, w)`` on leg ``k`` in two
    parts: to the leg's switch (behind its start: the table, then the closed form), and the
    rest of the exercise after it (the rest table) (s)."""
    t = 0.0
    length = float(prm[_LEG0 + _NL * k + _L.length])
    if q > length:
        size = math.prod(int(prm[_P.behind_shape + d]) for d in range(3))
        off = 3 * k * size
        e = q - length
        t, u, w = (_table3(tab, off + j * size, prm, e, u, w) for j in range(3))
        q = length
    dist = q - float(prm[_LEG0 + _NL * k + _L.switch])
    if dist > 0.0:
        tp, u, w = to_switch(prm, dist, u, w)
        dt = float(prm[_P.dt])
        t += math.ceil(tp / dt - 1e-9) * dt  # the switch comes on the next tick
    nu = int(prm[_P.rest_n])
    rest = int(prm[_P.rest_offset]) + k * nu * nu
    return t, table2(tab, rest, float(prm[_P.rest_u0]), float(prm[_P.rest_du]), nu, u, w)


def finish(prm: np.ndarray, tab: np.ndarray, k: int, q: float, u: float, w: float) -> float:
    """Time to finish the exercise from the 1-D state ``(q, u, w)`` on leg ``k`` (s)."""
    t, rest = finish_parts(prm, tab, k, q, u, w)
    return t + rest


def nominal_rest(prm: np.ndarray, tab: np.ndarray, k: int) -> float:
    """The rest of the exercise after leg ``k``'s switch at the guided plateau speed (s)."""
    nu = int(prm[_P.rest_n])
    rest = int(prm[_P.rest_offset]) + k * nu * nu
    ui = float(prm[_P.u_inf])
    return table2(tab, rest, float(prm[_P.rest_u0]), float(prm[_P.rest_du]), nu, ui, ui)


def estimate_parts(
    prm: np.ndarray,
    tab: np.ndarray,
    traj: Trajectory,
    leg: int,
    s: float,
    done: bool,
    x: tuple[float, float, float],
    v: tuple[float, float, float],
    c: tuple[float, float, float],
) -> tuple[float, float]:
    """:meth:`FastETC.times`' two parts from the guide state ``(leg, s, done)``, the hand's
    position ``x``, the admittance's velocity ``v`` and the command ``c`` (the twin takes the
    trajectory packed, :attr:`FastETC.path`): once done the braking time ``|c| / a`` and 0."""
    if done:
        return math.sqrt(c[0] * c[0] + c[1] * c[1] + c[2] * c[2]) * float(prm[_P.inv_acc]), 0.0
    s_end = float(prm[_LEG0 + _NL * leg + _L.end])
    q, u, w = _along(traj, s_end, s, list(x), list(v), list(c))
    return finish_parts(prm, tab, leg, q, u, w)
