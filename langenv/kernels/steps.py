"""The env's ticks, compiled: pacing, the user's force, the tick, speech, ``t_a`` and the rewards.

:func:`run` repeats, tick after tick, what ``LangCtrlEnv._tick`` does in the common case: the pace
laws (:meth:`PaceActuator.step <langenv.pacing.PaceActuator.step>`), a tabulated user's force
against the motion (:func:`~langenv.users.base.sample_table`,
:func:`~langenv.users.base.against_motion`), the compiled tick (:func:`langenv.kernels.tick.tick`),
the speech timeline's advance inside a phrase (:meth:`SpeechTimeline.step
<langenv.speech.timeline.SpeechTimeline.step>`), the speech ETC (:meth:`PhraseGraph.eta
<langenv.speech.graph.PhraseGraph.eta>`), the cooperation history and the reward integrands, the
same operations in the same order. It stops where Python has work to do: before a tick in which a
phrase's clip or slot ends (the next phrase is chosen in Python), after a tick whose control part
needs the Python parts (joint-limit avoidance, bad input), after a protective stop, and when both
motion and speech are over. ``es`` holds the env's state and settings (``E_*`` slots).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from langenv.kernels import inline, kernel
from langenv.kernels import tick as tk
from langenv.kernels.mjc import P_POW, py_square
from langenv.users import PerturbedUser, ReplayUser, SyntheticUser

__all__ = ["CompiledSteps", "eta", "pack_graph", "run"]

# env state
E_P, E_A, E_PDOT, E_TIME, E_TA, E_EM, E_PACE, E_VMAX = 0, 1, 2, 3, 4, 5, 6, 7
E_POS, E_ST, E_SA, E_MARK, E_U, E_COOPI, E_F = 8, 9, 10, 11, 12, 13, 14
# settings
E_KP, E_KA, E_PMIN, E_PMAX, E_AMIN, E_AMAX, E_DT, E_USTEP = 17, 18, 19, 20, 21, 22, 23, 24
E_SLOT = 25  # the current vertex's slot length (a pause vertex: its length as planned now)
E_TFAC = 26  # the pause rule's target over t_x (the target-duration action's factor)
N_ENV = 27

# run()'s answers
R_DONE, R_PYTHON, R_CONTROL, R_STOP, R_OVER = 0, 1, 2, 3, 4


def pack_graph(graph: Any, order: tuple[str, ...]) -> tuple[np.ndarray, ...]:
    """A phrase graph as arrays for :func:`eta`: ``mid`` (n), ``slot`` (n, 3: the nominal slot,
    its minimum and maximum, which differ for a pause only), by index in ``order``, the
    children's offsets ``kid_ptr`` (n + 1) and indexes ``kids``, in the graph's order."""
    index = {u: i for i, u in enumerate(order)}
    mid = np.array([graph._mid[u] for u in order])
    slot = np.array([(graph.slot(u), *graph.slot_range(u)) for u in order]).reshape(-1, 3)
    kids = [index[v] for u in order for v in graph.children(u)]
    counts = [len(graph.children(u)) for u in order]
    kid_ptr = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)
    return mid, slot, kid_ptr, np.array(kids, dtype=np.int64)


@inline
def _nearest(lo: int, hi: int, kids: np.ndarray, mid: np.ndarray, x: float) -> int:
    """The paper's choice among ``kids[lo:hi]`` (non-empty): the first whose ``mid`` is nearest
    ``x`` (``langenv.speech.graph._nearest``, comparison for comparison)."""
    best = kids[lo]
    best_err = abs(x - mid[best])
    for j in range(lo + 1, hi):
        v = kids[j]
        err = abs(x - mid[v])
        if err < best_err:
            best, best_err = v, err
    return int(best)


@kernel
def _fill(
    v: int, left: float, mid: np.ndarray, slot: np.ndarray, kid_ptr: np.ndarray, kids: np.ndarray
) -> float:
    """:meth:`PhraseGraph.pause_length <langenv.speech.graph.PhraseGraph.pause_length>` of the
    pause of index ``v`` (the same operations in the same order)."""
    y = left - slot[v, 0]
    rest = 0.0
    lo, hi = kid_ptr[v], kid_ptr[v + 1]
    while hi > lo:
        w = _nearest(lo, hi, kids, mid, y)
        rest += slot[w, 0]
        y -= slot[w, 0]
        lo, hi = kid_ptr[w], kid_ptr[w + 1]
    length = left - rest
    s_lo, s_hi = slot[v, 1], slot[v, 2]
    return s_lo if length < s_lo else (s_hi if length > s_hi else length)


@kernel
def eta(
    u: int,
    remaining: float,
    t_x: float,
    mid: np.ndarray,
    slot: np.ndarray,
    kid_ptr: np.ndarray,
    kids: np.ndarray,
) -> float:
    """:meth:`PhraseGraph.eta <langenv.speech.graph.PhraseGraph.eta>` of vertex index ``u``."""
    total = remaining
    left = t_x - remaining
    lo, hi = kid_ptr[u], kid_ptr[u + 1]
    while hi > lo:
        v = _nearest(lo, hi, kids, mid, left)
        length = (
            slot[v, 0] if slot[v, 1] == slot[v, 2] else _fill(v, left, mid, slot, kid_ptr, kids)
        )
        total += length
        left -= length
        lo, hi = kid_ptr[v], kid_ptr[v + 1]
    return total


@kernel
def _bounded(x: float, lo: float, hi: float) -> float:
    """Python's ``min(hi, max(lo, x))``."""
    x = x if x > lo else lo
    return x if x < hi else hi


@kernel
def _magnitude(table: np.ndarray, step: float, t: float) -> float:
    """:func:`~langenv.users.base.sample_table` (``t >= 0``)."""
    x = t / step
    k = int(x)
    last = table.shape[0] - 1
    if k >= last:
        return table[last] if x == last else 0.0
    f0 = table[k]
    f1 = table[k + 1]
    w = x - k
    if f0 == 0.0 or f1 == 0.0:
        return f0 if w < 0.5 else f1
    return f0 + w * (f1 - f0)


@kernel
def run(
    ws: np.ndarray,
    path: np.ndarray,
    aw: np.ndarray,
    ai: np.ndarray,
    jac: np.ndarray,
    xpos: np.ndarray,
    xmat: np.ndarray,
    qpos: np.ndarray,
    qvel: np.ndarray,
    ctrl: np.ndarray,
    qfrc: np.ndarray,
    prm: np.ndarray,
    tab: np.ndarray,
    ptr: np.ndarray,
    es: np.ndarray,
    hist: np.ndarray,
    table: np.ndarray,
    mid: np.ndarray,
    slot: np.ndarray,
    kid_ptr: np.ndarray,
    kids: np.ndarray,
    p_cmd: float,
    a_cmd: float,
    n: int,
) -> tuple[int, int, int]:
    """Up to ``n`` ticks of the env (speech going on iff ``es[E_U] >= 0``).

    Returns:
        ``(ticks done, answer, code)``: :data:`R_DONE` after ``n`` ticks; :data:`R_PYTHON`: the
        next tick is Python's (nothing of it done); :data:`R_CONTROL`: the last tick's control
        part answered ``code`` (pacing and the user's force ``es[E_F:E_F+3]`` done, the rest is
        Python's); :data:`R_STOP`: the last tick ended in a protective stop (``code``: the
        limit); :data:`R_OVER`: motion and speech are over after the last tick.
    """
    dt = es[E_DT]
    u = int(es[E_U])
    pow_fn = ptr[P_POW]
    size = hist.shape[0]
    for i in range(n):
        p, a = es[E_P], es[E_A]
        p_new = _bounded(p + dt * es[E_KP] * (p_cmd - p), es[E_PMIN], es[E_PMAX])
        p_dot = (p_new - p) / dt
        a = _bounded(a + dt * es[E_KA] * (a_cmd - a), es[E_AMIN], es[E_AMAX])
        adv = a * dt
        if u >= 0 and not es[E_POS] + adv < es[E_MARK]:
            return i, R_PYTHON, 0  # a clip or slot ends: the next phrase is Python's
        t = es[E_TIME]
        if not t >= 0.0:
            return i, R_PYTHON, 0
        mag = _magnitude(table, es[E_USTEP], t)
        f0 = f1 = f2 = 0.0
        if mag != 0.0:
            b0, b1, b2 = ws[tk.S_TAN], ws[tk.S_TAN + 1], ws[tk.S_TAN + 2]
            norm = math.sqrt(b0 * b0 + b1 * b1 + b2 * b2)
            if not (math.isfinite(norm) and norm > 1e-12):
                return i, R_PYTHON, 0  # the user's ConfigError
            k = -mag / norm
            f0, f1, f2 = b0 * k, b1 * k, b2 * k
        es[E_P], es[E_PDOT], es[E_A] = p_new, p_dot, a
        es[E_F], es[E_F + 1], es[E_F + 2] = f0, f1, f2
        code, stop = tk.tick(
            ws, path, aw, ai, jac, xpos, xmat, qpos, qvel, ctrl, qfrc, prm, tab, ptr,
            f0, f1, f2, f0, f1, f2, p_new, p_dot,
        )  # fmt: skip
        if code != tk.OK:
            return i + 1, R_CONTROL, code
        speed = ws[tk.S_HS]
        if stop != tk.STOP_NONE:
            es[E_TIME] = t + dt
            es[E_VMAX] = speed if speed > es[E_VMAX] else es[E_VMAX]
            return i + 1, R_STOP, stop
        t_x = ws[tk.S_TX]
        t_a = 0.0
        if u >= 0:
            es[E_SA] = a
            es[E_POS] += adv
            es[E_ST] += dt
            pos = es[E_POS]
            if slot[u, 1] < slot[u, 2]:  # an open pause: its length planned again
                length = _fill(u, pos + t_x * es[E_TFAC], mid, slot, kid_ptr, kids)
                es[E_SLOT] = length if length > pos else pos
                es[E_MARK] = es[E_SLOT]
            t_a = eta(u, es[E_SLOT] - pos, t_x, mid, slot, kid_ptr, kids)
        es[E_TIME] = t + dt
        ci = int(es[E_COOPI])
        hist[ci % size] = ws[tk.S_C]
        es[E_COOPI] = ci + 1
        es[E_TA] = t_a
        motion_on, speech_on = math.isnan(ws[tk.S_TEND]), u >= 0
        em = abs(t_a / a - t_x / p_new) if (motion_on or speech_on) else 0.0
        pace = (py_square(pow_fn, p_new - 1.0) if motion_on else 0.0) + (
            py_square(pow_fn, a - 1.0) if speech_on else 0.0
        )
        es[E_EM] += em * dt
        es[E_PACE] += pace * dt
        es[E_VMAX] = speed if speed > es[E_VMAX] else es[E_VMAX]
        if not motion_on and not speech_on:
            return i + 1, R_OVER, 0
    return n, R_DONE, 0


class CompiledSteps:
    """:func:`run` bound to one ``LangCtrlEnv`` (typed ``Any``: ``langenv.env`` imports this
    module): loads the env's state into ``es`` before the ticks and writes it back after them.

    The compiled ticks apply when the motion's tick is compiled and running, the user is a
    :class:`~langenv.users.SyntheticUser`, :class:`~langenv.users.PerturbedUser` or
    :class:`~langenv.users.ReplayUser` (a tabulated force against the motion), the force sensor
    has no noise (its draws stay in Python) and the arm's joints are the model's (:meth:`usable`);
    otherwise the env ticks in Python.
    """

    def __init__(self, env: Any) -> None:
        self.env = env
        speech = env.speech
        self.order: tuple[str, ...] = tuple(speech.graph.phrases)
        self.index = {u: i for i, u in enumerate(self.order)}
        self.mid, self.slot, self.kid_ptr, self.kids = pack_graph(speech.graph, self.order)
        es = np.zeros(N_ENV)
        lim = env.paces.limits
        es[E_KP], es[E_KA] = lim.k_p, lim.k_a
        es[E_PMIN], es[E_PMAX], es[E_AMIN], es[E_AMAX] = lim.p_min, lim.p_max, lim.a_min, lim.a_max
        es[E_DT] = env.dt
        self.es = es

    def usable(self) -> bool:
        """Whether the compiled ticks apply now (see the class docstring)."""
        m = self.env.motion
        tick = m._compiled
        return (
            tick is not None
            and m.safety_stop is None
            and tick._full_dofs
            and not m.sensor.noise_std > 0.0
            and type(self.env.user) in (SyntheticUser, PerturbedUser, ReplayUser)
        )

    def run(
        self, p_cmd: float, a_cmd: float, n: int, em_int: float, pace_int: float
    ) -> tuple[int, int, int, float, float]:
        """Up to ``n`` ticks (:func:`run`); returns its answer and the reward integrals."""
        args: tuple[Any, ...] = (*self.load(em_int, pace_int), p_cmd, a_cmd, n)
        done, answer, code = run(*args)
        if done:
            em_int, pace_int = self.store()
        return done, answer, code, em_int, pace_int

    def load(self, em_int: float, pace_int: float) -> tuple[np.ndarray, ...]:
        """The env's state into ``es`` (before compiled ticks); returns the arrays :func:`run`
        takes first (``ws`` ... ``kids``), in order."""
        env, es = self.env, self.es
        paces, speech = env.paces, env.speech
        table, step = env.user.force_table()
        u = speech._phrase
        es[E_P : E_COOPI + 1] = (  # one slice assignment: the layout is E_P .. E_COOPI in order
            paces.p, paces.a, paces.p_dot, env.time, env.t_a, em_int, pace_int, env._max_speed,
            speech._pos, speech._t, speech._a, speech._mark,
            -1.0 if u is None else self.index[u], env._coop_i,
        )  # fmt: skip
        es[E_USTEP] = step
        es[E_SLOT] = speech.slot_length
        es[E_TFAC] = env._pause_factor
        t = env.motion._compiled
        return (
            t.ws, t.path, t.aw, t.ai, t.jac, t.xpos, t.xmat, t.qpos, t.qvel, t.ctrl, t.qfrc,
            t.prm, t.tab, t.ptr, es, env._coop_hist, table, self.mid, self.slot, self.kid_ptr,
            self.kids,
        )  # fmt: skip

    def store(self) -> tuple[float, float]:
        """``es`` back into the env's state (after compiled ticks); returns the reward integrals."""
        env, es = self.env, self.es
        paces, speech, motion = env.paces, env.speech, env.motion
        (
            paces.p, paces.a, paces.p_dot, env.time, env.t_a, em_int, pace_int,
            env._max_speed, speech._pos, speech._t, speech._a, mark, _, coop_i,
        ) = es[E_P : E_COOPI + 1].tolist()  # fmt: skip
        env._coop_i = int(coop_i)
        if speech._elastic:  # an open pause's length, planned again at each tick
            speech._mark = mark
            speech._cur_slot = float(es[E_SLOT])
        motion.f_user = es[E_F : E_F + 3].copy()
        motion._compiled.sync()
        return em_int, pace_int
