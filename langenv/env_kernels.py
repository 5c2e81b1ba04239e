"""The env's ticks, compiled: pacing, the user's force, the tick, speech, ``t_a`` and the rewards.

:func:`run` repeats, tick after tick, what ``LangCtrlEnv._tick`` does in the common case: the pace
laws (:func:`langenv.control.pacing_kernels.step`), a tabulated user's force against the motion
(:mod:`langenv.users.table_kernels`), the compiled tick (:func:`langenv.motion.tick_kernels.tick`),
the speech timeline's advance inside a vertex (:meth:`SpeechTimeline.step
<langenv.speech.timeline.SpeechTimeline.step>`), the speech ETC
(:func:`langenv.speech.graph_kernels.eta`), the cooperation history and the reward integrands
(:func:`langenv.task.reward_kernels.integrands`), the same operations in the same order. It stops
where Python has work to do: before a tick in which a phrase's clip or slot ends (the next
phrase is chosen in Python), after a tick whose control part needs the Python parts (joint-limit
avoidance, bad input), after a protective stop, and when both motion and speech are over.

Every kernel takes a session's one record, :data:`SESSION` (its arrays' addresses: the tick's,
the env's, the phrase graph's), and views the arrays it reads; the single env and the batch
(:mod:`langenv.batch.kernels`) call the same :func:`run` on it. ``es`` is :data:`ENV_STEPS`: the
pace actuator's, the speech timeline's and the env's own declarations. :func:`run_law` adds the
paper's aligner, decided every tick (:func:`langenv.control.pacing_kernels.law_commands`), for
``LangCtrlEnv.run_law``.
"""

from __future__ import annotations

import math

import numpy as np

from langenv.control.pacing import PACE_LAW, PACE_SETTINGS, PACE_STATE
from langenv.control.pacing_kernels import law_commands
from langenv.control.pacing_kernels import step as pace_step
from langenv.kernels import kernel
from langenv.kernels.mjc import P_POW
from langenv.kernels.views import Record, array_table, f8, f8_2, i8
from langenv.layout import Layout, field_table
from langenv.motion import tick_kernels as mk
from langenv.speech.graph_kernels import eta, fill
from langenv.speech.legs_kernels import gate, horizon, motion_segment, segment
from langenv.speech.timeline import TIMELINE_STATE
from langenv.task import reward_kernels as rk
from langenv.users.table_kernels import against_motion, magnitude

__all__ = [
    "ENV_SETTINGS",
    "ENV_STATE",
    "ENV_STEPS",
    "LAW",
    "ROW_FIELDS",
    "R_CONTROL",
    "R_DONE",
    "R_OVER",
    "R_PYTHON",
    "R_STOP",
    "SESSION",
    "run",
    "run_law",
]

ENV_TIMES = field_table(
    """
    time       the env's time since the reset (s)
    t_a        the speech ETC after the last tick (s)
    t_h        the motion's time to the end of the horizon segment after the last tick (s)
    em_int     the step's misalignment integral so far (s^2)
    pace_int   the step's pace objective integral so far (s)
    max_speed  the step's highest hand speed so far (m/s)
    """
)
ENV_STATE = field_table(
    """
    coop_i:int    cooperation samples taken (the history's write index)
    user_step     the user's force table's step (s)
    pause_factor  the pause rule's target over t_x (the target action's factor)
    reopen_at     from when Python looks whether the speech goes on after its end (s; inf: never)
    f_user[3]     the person's force in the last tick (N)
    """
)
"""The env's own state in its compiled ticks (with :data:`ENV_TIMES`)."""
ENV_SETTINGS = field_table(
    """
    dt  the tick (s)
    """
)
"""The env's own settings."""

ENV_STEPS = Layout(
    "env_steps", PACE_STATE, ENV_TIMES, TIMELINE_STATE, ENV_STATE, PACE_SETTINGS, ENV_SETTINGS
)
"""``es``: the pace actuator's state, the env's times, the speech timeline's state, the env's
own state, then the pace laws' and the env's settings."""

LAW = Layout(
    "law",
    PACE_LAW,
    field_table(
        """
        w_em     the env's misalignment weight
        w_pace   the env's pace weight
        t_scale  the observation's time scale (s)
        """
    ),
)
"""The law and the env's reward weights as :func:`run_law` reads them."""

ROW_FIELDS = (
    "time", "cooperation", "hand_speed", "p", "a", "t_x", "t_a", "em", "motion_done",
    "speech_done", "leg", "path_deviation",
)  # fmt: skip
"""The info values :func:`run_law` records after each step, in its rows' first columns (then the
joint positions and the person's force)."""
_N_ROW = len(ROW_FIELDS)

SESSION = Record(
    "session",
    mk.TICK_ARRAYS,
    array_table(
        """
        es             the env's ticks' array (:data:`ENV_STEPS`)
        hist           the cooperation history (a ring)
        table          the user's force table
        mid            the graph's mid-lengths
        slot           the graph's slots (n, 3)
        kid_ptr:int64  the graph's children offsets
        kids:int64     the graph's children
        lg             the graph's legs (``LegPlan.packed``)
        tails:float32  the observation's child blocks per vertex and the end's
        dur            each vertex's clip length at a = 1 (s)
        """
    ),
)
"""A session's arrays, reached by address (:mod:`langenv.kernels.views`): the tick's
(:data:`~langenv.motion.tick_kernels.TICK_ARRAYS`, first), the env's, the phrase graph's in
:meth:`LangCtrlEnv.compiled_steps <langenv.env.LangCtrlEnv.compiled_steps>`'s order and the
observation's. One int64 row per session, built by :class:`~langenv.compiled_steps.CompiledSteps`;
what :func:`run`, :func:`run_law` and the batch's kernels (:mod:`langenv.batch.kernels`) take."""

R_DONE, R_PYTHON, R_CONTROL, R_STOP, R_OVER = 0, 1, 2, 3, 4
""":func:`run`'s answers (see there)."""

_E = ENV_STEPS.at
_S = SESSION.at
_T = mk.TICK.at
_L = LAW.at


@kernel
def run(s: np.ndarray, p_cmd: float, a_cmd: float, n: int) -> tuple[int, int, int]:
    """Up to ``n`` ticks of the env of the session ``s`` (its :data:`SESSION` row; speech going
    on iff ``es[phrase] >= 0``), with the step's pace commands ``p_cmd``, ``a_cmd``.

    Returns:
        ``(ticks done, answer, code)``: :data:`R_DONE` after ``n`` ticks; :data:`R_PYTHON`: the
        next tick is Python's (nothing of it done: a phrase's end, or the motion going on from
        ``es[reopen_at]`` after the speech's end); :data:`R_CONTROL`: the last tick's control
        part answered ``code`` (pacing and the user's force ``es[f_user]`` done, the rest is
        Python's); :data:`R_STOP`: the last tick ended in a protective stop (``code``: the
        limit); :data:`R_OVER`: motion and speech are over after the last tick.
    """
    ws, es, hist, table = f8(s, _S.ws), f8(s, _S.es), f8(s, _S.hist), f8(s, _S.table)
    mid, slot, kid_ptr, kids = f8(s, _S.mid), f8_2(s, _S.slot, 3), i8(s, _S.kid_ptr), i8(s, _S.kids)
    lg = f8(s, _S.lg)
    dt = es[_E.dt]
    u = int(es[_E.phrase])
    pow_fn = i8(s, _S.ptr)[P_POW]
    size = hist.shape[0]
    for i in range(n):
        if u < 0 and es[_E.time] >= es[_E.reopen_at] and math.isnan(ws[_T.t_end]):
            return i, R_PYTHON, 0  # the speech may go on after its end: Python decides
        p_new, p_dot, a = pace_step(
            es[_E.p], es[_E.a], p_cmd, a_cmd, dt, es[_E.k_p], es[_E.k_a], es[_E.p_min],
            es[_E.p_max], es[_E.a_min], es[_E.a_max],
        )  # fmt: skip
        adv = a * dt
        if u >= 0 and not es[_E.speech_pos] + adv < es[_E.mark]:
            return i, R_PYTHON, 0  # a clip or slot ends: the next phrase is Python's
        t = es[_E.time]
        if not t >= 0.0:
            return i, R_PYTHON, 0
        mag = magnitude(table, es[_E.user_step], t)
        f0 = f1 = f2 = 0.0
        if mag != 0.0:
            ok, f0, f1, f2 = against_motion(
                mag, ws[_T.tangent], ws[_T.tangent + 1], ws[_T.tangent + 2]
            )
            if not ok:
                return i, R_PYTHON, 0  # the user's ConfigError
        es[_E.p], es[_E.p_dot], es[_E.a] = p_new, p_dot, a
        es[_E.f_user], es[_E.f_user + 1], es[_E.f_user + 2] = f0, f1, f2
        code, stop = mk.tick(s, f0, f1, f2, f0, f1, f2, p_new, p_dot)
        if code != mk.OK:
            return i + 1, R_CONTROL, code
        speed = ws[_T.hand_speed]
        if stop != 0:
            es[_E.time] = t + dt
            es[_E.max_speed] = speed if speed > es[_E.max_speed] else es[_E.max_speed]
            return i + 1, R_STOP, stop
        t_x = ws[_T.t_x]
        t_a = 0.0
        t_h = t_x
        if u >= 0:
            es[_E.speech_a] = a
            es[_E.speech_pos] += adv
            es[_E.speech_t] += dt
            pos = es[_E.speech_pos]
            t_leg, leg = ws[_T.t_leg], int(ws[_T.leg])
            if slot[u, 1] < slot[u, 2]:  # an open pause: its length planned again
                h = horizon(lg, segment(lg, u), t_x, t_leg, leg)
                f = 1.0 if gate(lg, u) else es[_E.pause_factor]
                length = fill(u, pos + h * f, mid, slot, kid_ptr, kids, lg)
                es[_E.slot] = length if length > pos else pos
                es[_E.mark] = es[_E.slot]
            last = motion_segment(lg, leg)
            j = segment(lg, kids[kid_ptr[u]]) if kid_ptr[u + 1] > kid_ptr[u] else segment(lg, u)
            last = j if j > last else last
            t_a = eta(u, es[_E.slot] - pos, t_x, t_leg, leg, last, mid, slot, kid_ptr, kids, lg)
            t_h = horizon(lg, last, t_x, t_leg, leg)
        es[_E.time] = t + dt
        ci = int(es[_E.coop_i])
        hist[ci % size] = ws[_T.c]
        es[_E.coop_i] = ci + 1
        es[_E.t_a] = t_a
        es[_E.t_h] = t_h
        motion_on, speech_on = math.isnan(ws[_T.t_end]), u >= 0
        em, pace = rk.integrands(pow_fn, t_a, a, t_h, p_new, motion_on, speech_on)
        es[_E.em_int] += em * dt
        es[_E.pace_int] += pace * dt
        es[_E.max_speed] = speed if speed > es[_E.max_speed] else es[_E.max_speed]
        if not motion_on and not speech_on:
            return i + 1, R_OVER, 0
    return n, R_DONE, 0


@kernel
def run_law(
    s: np.ndarray, law: np.ndarray, rows: np.ndarray, rewards: np.ndarray
) -> tuple[int, int, int]:
    """Up to ``rows.shape[0]`` one-tick steps of the law (``law``: :data:`LAW`) by the session
    ``s`` (its :data:`SESSION` row; the env at 500 Hz).

    At 500 Hz an analytic aligner takes one env step per tick, and the Python around each tick
    (observation, policy, info, the return to Python) costs several times the tick. When the
    policy is exactly the law of :class:`~langenv.control.pacing.PaceLaw`, this repeats, tick after
    tick and without leaving compiled code, what the policy and the env do for one step: the
    observation's fields the law reads rounded to float32 as the observation stores them, the
    law, the action rounded to float32, the env's map from action to pace commands, then
    :func:`run` for one tick, and the step's reward and the info values the episode log keeps.
    The same operations in the same order, so episodes are bit-identical to the policy stepping
    the env (``tests/test_pace_law.py``).

    Each finished step writes its info values (:data:`ROW_FIELDS`), the joint positions and the
    person's force into ``rows[k]`` and its reward into ``rewards[k]``.

    Returns:
        ``(steps finished, answer, code)``: as :func:`run`'s answer for the tick that stopped
        the run; a tick ending in :data:`R_CONTROL`, :data:`R_STOP` or :data:`R_OVER` is done
        and its step is Python's to finish (not counted, not recorded); before
        :data:`R_PYTHON` nothing of the next step is done.
    """
    ws, es, qpos = f8(s, _S.ws), f8(s, _S.es), f8(s, _S.qpos)
    n_q = qpos.shape[0]
    t_scale = law[_L.t_scale]
    for k in range(rows.shape[0]):
        motion_on = math.isnan(ws[_T.t_end])
        p_cmd, a_cmd = law_commands(
            law[_L.k_ca], law[_L.k_em], law[_L.em_clip], law[_L.law_p_max], law[_L.law_a_max],
            law[_L.c_min], t_scale, es[_E.p_max], es[_E.a_max], es[_E.t_h], es[_E.t_a],
            ws[_T.c], motion_on,
        )  # fmt: skip
        es[_E.em_int] = 0.0
        es[_E.pace_int] = 0.0
        es[_E.max_speed] = 0.0
        _, answer, code = run(s, p_cmd, a_cmd, 1)
        if answer != R_DONE:
            return k, answer, code
        r_em, r_pace = rk.step_terms(
            es[_E.em_int], es[_E.pace_int], law[_L.w_em], law[_L.w_pace], t_scale
        )
        rewards[k] = rk.total(r_em, r_pace, 0.0)
        row = rows[k]
        t_x, t_a = es[_E.t_h], es[_E.t_a]
        row[0], row[1], row[2] = es[_E.time], ws[_T.c], ws[_T.hand_speed]
        row[3], row[4], row[5], row[6] = es[_E.p], es[_E.a], t_x, t_a
        row[7] = t_a - t_x
        row[8] = 0.0 if math.isnan(ws[_T.t_end]) else 1.0
        row[9] = 1.0 if es[_E.phrase] < 0.0 else 0.0
        row[10] = ws[_T.leg]
        row[11] = ws[_T.path_deviation]
        for j in range(n_q):
            row[_N_ROW + j] = qpos[j]
        for j in range(3):
            row[_N_ROW + n_q + j] = es[_E.f_user + j]
    return rows.shape[0], R_DONE, 0
