"""FastETC compiled: its leg law (building the tables) and its evaluation (the closed form of a
leg, its tables, and the projection).

The parameters and tables of a :class:`~langenv.control.motion_etc.FastETC` are packed in two
float64 arrays: ``prm`` (:data:`~langenv.control.motion_etc.ETC_PARAMS`, then per leg a row of
:data:`~langenv.control.motion_etc.ETC_LEG`) and ``tab`` (the tables, flat).
:func:`estimate_parts` is ``FastETC.times`` (``FastETC.etc`` their sum); :func:`simulate` is the
leg law :meth:`langenv.control.motion_etc._Law.simulate` (each state runs its own loop of the
same discrete update, element by element, the same operations as the vectorised NumPy version, so
the tables are bit-identical; building them takes a fraction of a second instead of seconds).
"""

from __future__ import annotations

import math

import numpy as np

from langenv.control.trajectory_kernels import frame, locate
from langenv.kernels import kernel
from langenv.layout import Layout, field_table

__all__ = [
    "ETC_LEG",
    "ETC_PARAMS",
    "estimate_parts",
    "finish",
    "finish_parts",
    "nominal_rest",
    "ramp_end",
    "simulate",
    "table2",
    "to_switch",
]

ETC_PARAMS = Layout(
    "etc_params",
    field_table(
        """
        dt                   the law's tick (s)
        acc                  the command's acceleration limit (m/s^2)
        u_inf                the guided plateau speed (m/s)
        tau                  the admittance's time constant M0/D0 (s)
        tau_d                1/tau (1/s)
        inv_acc              1/acc (s^2/m)
        behind_origin[3]     the behind-the-start tables' grid origin (m, m/s, m/s)
        behind_step[3]       their grid steps
        behind_shape[3]:int  their shape
        rest_u0              the rest tables' first speed (m/s)
        rest_du              their speed step (m/s)
        rest_n:int           their points per axis
        n_legs:int           number of legs
        rest_offset:int      where the rest tables start in ``tab``
        """
    ),
)
"""FastETC's ``prm``: its law and the tables' grids; then a row of :data:`ETC_LEG` per leg."""
ETC_LEG = Layout(
    "etc_leg",
    field_table(
        """
        end     the leg's end (arc length, m)
        length  its length (m)
        switch  its switch distance before the end (m)
        """
    ),
)
"""One leg's row of FastETC's ``prm`` (from ``ETC_PARAMS.size`` on)."""

_P = ETC_PARAMS.at
_L = ETC_LEG.at
_LEG0 = ETC_PARAMS.size
_NL = ETC_LEG.size
"""Index of the first leg's entries in ``prm``: per leg its end, length and switch distance."""


@kernel
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
    return (1.0 - a) * (tab[r0 + k] + b * (tab[r0 + k + 1] - tab[r0 + k])) + a * (
        tab[r1 + k] + b * (tab[r1 + k + 1] - tab[r1 + k])
    )


@kernel
def _clamp(v: float, hi: float) -> float:
    v = 0.0 if 0.0 > v else v  # Python's max(v, 0.0)
    return hi if hi < v else v  # min(v, hi)


@kernel
def _table3(tab: np.ndarray, off: int, prm: np.ndarray, x: float, y: float, z: float) -> float:
    """Trilinear lookup in a behind-the-start table, clamped at its edges."""
    nx, ny, nz = (
        int(prm[_P.behind_shape]),
        int(prm[_P.behind_shape + 1]),
        int(prm[_P.behind_shape + 2]),
    )
    fi = _clamp((x - prm[_P.behind_origin]) / prm[_P.behind_step], nx - 1.000001)
    fj = _clamp((y - prm[_P.behind_origin + 1]) / prm[_P.behind_step + 1], ny - 1.000001)
    fk = _clamp((z - prm[_P.behind_origin + 2]) / prm[_P.behind_step + 2], nz - 1.000001)
    i, j, k = int(fi), int(fj), int(fk)
    a, b, c = fi - i, fj - j, fk - k
    base = off + (i * ny + j) * nz + k
    out = 0.0
    for di in range(2):
        wa = 1.0 - a if di == 0 else a
        for dj in range(2):
            wb = 1.0 - b if dj == 0 else b
            n = base + di * ny * nz + dj * nz
            out += wa * wb * (tab[n] + c * (tab[n + 1] - tab[n]))
    return out


@kernel
def _g(t: float, s: float, ui: float, u0: float, w0: float, tau: float, acc: float) -> float:
    return s * (ui + (u0 - ui) * math.exp(-t / tau) - w0) - acc * t


@kernel
def ramp_end(prm: np.ndarray, u0: float, w0: float) -> tuple[float, float]:
    """When the command catches up with ``v_ref`` on a leg: ``(time, direction)``."""
    ui, tau, acc = prm[_P.u_inf], prm[_P.tau], prm[_P.acc]
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
    if _g(0.0, s, ui, u0, w0, tau, acc) <= 0.0:
        lo = (tau if tau < hi else hi) * 1e-3
        while _g(lo, s, ui, u0, w0, tau, acc) <= 0.0 and lo < hi:
            lo *= 2.0
    # Bisection: up to 60 halvings, until the bracket is under 1 us. Two halvings per round,
    # the second's two possible midpoints evaluated beside the first's (independent, so the
    # CPU overlaps their exp): the same midpoints and decisions as one halving at a time.
    k = 0
    while k < 60:
        mid = 0.5 * (lo + hi)
        left, right = 0.5 * (lo + mid), 0.5 * (mid + hi)
        g_mid = _g(mid, s, ui, u0, w0, tau, acc)
        g_left = _g(left, s, ui, u0, w0, tau, acc)
        g_right = _g(right, s, ui, u0, w0, tau, acc)
        if g_mid > 0.0:
            lo, nxt, g_nxt = mid, right, g_right
        else:
            hi, nxt, g_nxt = mid, left, g_left
        k += 1
        if hi - lo < 1e-6 or k == 60:
            break
        if g_nxt > 0.0:
            lo = nxt
        else:
            hi = nxt
        k += 1
        if hi - lo < 1e-6:
            break
    return hi, s


@kernel
def _time_to_cover(prm: np.ndarray, dist: float, u0: float) -> float:
    if dist <= 0.0:
        return 0.0
    ui, tau = prm[_P.u_inf], prm[_P.tau]
    a = (u0 - ui) * prm[_P.tau_d]
    t = (dist - a) / ui
    if t < 0.0:
        t = 0.0
    for _ in range(30):
        ex = math.exp(-t / tau)
        g = ui * t + a * (1.0 - ex) - dist
        dg = ui + a / tau * ex
        if dg <= 0.0:
            dg = ui
        step = g / dg
        t -= step
        if t < 0.0:
            t = 0.0
        if -1e-7 < step < 1e-7:
            break
    return t


@kernel
def to_switch(prm: np.ndarray, dist: float, u0: float, w0: float) -> tuple[float, float, float]:
    """Time for a leg's motion from ``(u0, w0)`` to cover ``dist`` and ``(u, w)`` then."""
    ui, tau, acc = prm[_P.u_inf], prm[_P.tau], prm[_P.acc]
    t_c, s = ramp_end(prm, u0, w0)
    if t_c > 0.0:
        reach = w0 * t_c + 0.5 * s * acc * t_c * t_c
        if reach >= dist:  # the switch comes during the ramp
            disc = w0 * w0 + 2.0 * s * acc * dist
            root = math.sqrt(0.0 if 0.0 > disc else disc)  # Python's max(disc, 0.0)
            t = (-w0 + root) / acc if s > 0 else (w0 - root) / acc
            return t, ui + (u0 - ui) * math.exp(-t / tau), w0 + s * acc * t
        u0 = ui + (u0 - ui) * math.exp(-t_c / tau)
        dist -= reach
    t = _time_to_cover(prm, dist, u0)
    u = ui + (u0 - ui) * math.exp(-t / tau)
    return t_c + t, u, u


@kernel
def finish(prm: np.ndarray, tab: np.ndarray, k: int, q: float, u: float, w: float) -> float:
    """Time to finish the exercise from the 1-D state ``(q, u, w)`` on leg ``k`` (s)."""
    t, rest = finish_parts(prm, tab, k, q, u, w)
    return t + rest


@kernel
def finish_parts(
    prm: np.ndarray, tab: np.ndarray, k: int, q: float, u: float, w: float
) -> tuple[float, float]:
    """:func:`finish` in two parts: the time to leg ``k``'s switch, and the rest of the
    exercise after it (s)."""
    t = 0.0
    length = prm[_LEG0 + _NL * k + _L.length]
    if q > length:
        size = (
            int(prm[_P.behind_shape])
            * int(prm[_P.behind_shape + 1])
            * int(prm[_P.behind_shape + 2])
        )
        off = 3 * k * size
        e = q - length
        t, u, w = (
            _table3(tab, off, prm, e, u, w),
            _table3(tab, off + size, prm, e, u, w),
            _table3(tab, off + 2 * size, prm, e, u, w),
        )
        q = length
    dist = q - prm[_LEG0 + _NL * k + _L.switch]
    if dist > 0.0:
        tp, u, w = to_switch(prm, dist, u, w)
        dt = prm[_P.dt]
        t += math.ceil(tp / dt - 1e-9) * dt  # the switch comes on the next tick
    nu = int(prm[_P.rest_n])
    rest = int(prm[_P.rest_offset]) + k * nu * nu
    return t, table2(tab, rest, prm[_P.rest_u0], prm[_P.rest_du], nu, u, w)


@kernel
def nominal_rest(prm: np.ndarray, tab: np.ndarray, k: int) -> float:
    """The rest of the exercise after leg ``k``'s switch at the guided plateau speed (s)."""
    nu = int(prm[_P.rest_n])
    rest = int(prm[_P.rest_offset]) + k * nu * nu
    ui = prm[_P.u_inf]
    return table2(tab, rest, prm[_P.rest_u0], prm[_P.rest_du], nu, ui, ui)


@kernel
def estimate_parts(
    prm: np.ndarray,
    tab: np.ndarray,
    path: np.ndarray,
    leg: int,
    s: float,
    done: bool,
    x: tuple[float, float, float],
    v: tuple[float, float, float],
    c: tuple[float, float, float],
) -> tuple[float, float]:
    """``FastETC.times``: the time to complete the exercise from the state in two parts (s),
    the time to the current leg's switch (once done: the braking time) and the rest of the
    exercise after it (0 once done); ``FastETC.etc`` is their sum.

    Args:
        prm, tab: The packed FastETC.
        path: The packed trajectory.
        leg, s, done: The guide state.
        x: Hand position (m).
        v: The admittance's reference velocity (m/s).
        c: The velocity command (m/s).
    """
    if done:
        return math.sqrt(c[0] * c[0] + c[1] * c[1] + c[2] * c[2]) * prm[_P.inv_acc], 0.0
    s_end = prm[_LEG0 + _NL * leg + _L.end]
    i, t = locate(path, s, s >= s_end)
    xd0, xd1, xd2, b0, b1, b2, _, _, _, _ = frame(path, i, t)
    q = s_end - s - ((x[0] - xd0) * b0 + (x[1] - xd1) * b1 + (x[2] - xd2) * b2)
    u = v[0] * b0 + v[1] * b1 + v[2] * b2
    w = c[0] * b0 + c[1] * b1 + c[2] * b2
    return finish_parts(prm, tab, leg, q, u, w)


@kernel
def simulate(
    q: np.ndarray,
    u: np.ndarray,
    w: np.ndarray,
    y: np.ndarray,
    ul: np.ndarray,
    wl: np.ndarray,
    length: float,
    q_sw: float,
    f_prop: float,
    k: float,
    decay: float,
    gain: float,
    dw: float,
    dt: float,
    n_ticks: int,
    out: np.ndarray,
) -> None:
    """The law from each state ``(q, u, w)`` (lateral ``(y, ul, wl)``) until it switches.

    ``out`` (4, n): time (``inf`` if not switched within ``n_ticks``), ``q``, ``u``, ``w``.
    """
    kg = k * gain
    for i in range(q.shape[0]):
        qi, ui, wi, yi, uli, wli = q[i], u[i], w[i], y[i], ul[i], wl[i]
        t = math.inf
        for n in range(n_ticks):
            if qi < q_sw:
                t = n * dt
                break
            e = qi - length
            f = f_prop + k * (e if e > 0.0 else 0.0)
            ui = ui * decay + f * gain
            uli = uli * decay - kg * yi
            du, dl = ui - wi, uli - wli
            norm = math.sqrt(du * du + dl * dl)
            scale = dw / (norm if norm > 1e-300 else 1e-300) if norm > dw else 1.0
            wi = wi + du * scale
            wli = wli + dl * scale
            qi = qi - wi * dt
            yi = yi + wli * dt
        out[0, i], out[1, i], out[2, i], out[3, i] = t, qi, ui, wi
