"""N sessions stepped in one compiled call: the batch's kernels.

Each session of a :class:`~langenv.batch.env.LangCtrlVectorEnv` is a whole ``LangCtrlEnv``
whose compiled arrays (the tick's, the arm's, MuJoCo's, the env's ticks', the phrase graph's,
the user's force table) stay where they are; the batch keeps a table of the sessions' records
(:data:`langenv.env_kernels.SESSION`: their arrays' addresses, one row per session, each the
row the single env steps with) and a control row per session (:data:`CONTROL`: the step's pace
commands, ticks left, the answer). :func:`run_parallel` runs
:func:`langenv.env_kernels.run` for every active session, spread over the cores by Numba's
``prange`` (threads, without the GIL; MuJoCo's ``mj_step`` on separate ``mjData`` is
thread-safe); :func:`run_serial` runs a list of sessions in the calling thread (without the
GIL: a thread pool may call it). :func:`begin` turns a batch of actions into pace commands and
starts the step's integrals; :func:`observe` writes each session's observation, reward terms
and info values after the step, the same values the env computes in Python
(``tests/test_batch.py``).
"""

from __future__ import annotations

import math

import numba
import numpy as np

from langenv import env_kernels as ek
from langenv.control.pacing_kernels import command_from_action as command
from langenv.kernels import jit, kernel
from langenv.kernels.views import f4_2, f8, i8
from langenv.layout import Layout, field_table
from langenv.motion import tick_kernels as mk
from langenv.task import observation_kernels as ok
from langenv.task import reward_kernels as rk
from langenv.task.observation import TREND_WINDOW

__all__ = [
    "CONTROL",
    "INFO",
    "begin",
    "observe",
    "run_parallel",
    "run_serial",
]

CONTROL = Layout(
    "control",
    field_table(
        """
        active:bool  the session takes part in this round
        p_cmd        the step's physical pace command
        a_cmd        the step's audio pace command
        left:int     ticks of the step still to run
        answer:int   :func:`langenv.env_kernels.run`'s answer
        code:int     and its code
        length       the trajectory's length (m)
        horizon      a step's length (s): the boundary flag's horizon
        t_speech     when the speech ended (s; NaN while it goes on)
        w_em         the env's misalignment weight
        w_pace       the env's pace weight
        p_max        the env's upper bound of p (the action map)
        a_max        the env's upper bound of a
        """
    ),
)
"""Per session: the step's commands and progress, and what :func:`observe` needs besides the
arrays (a float64 row)."""
INFO = (
    "time", "t_x", "t_a", "em", "p", "a", "cooperation", "hand_speed", "progress", "in_pause",
    "motion_done", "speech_done", "t_motion", "t_speech", "path_deviation", "max_hand_speed",
    "reward_em", "reward_pace", "reward", "phrase", "leg",
)  # fmt: skip
"""The columns of :func:`observe`'s info rows (flags as 0/1, ``t_motion``/``t_speech`` NaN while
going on, ``phrase`` the vertex's index or -1, ``leg`` the motion's leg index)."""

_S = ek.SESSION.at
_C = CONTROL.at
_E = ek.ENV_STEPS.at
_T = mk.TICK.at
_N_INFO = len(INFO)


@kernel
def _run_one(s: np.ndarray, c: np.ndarray) -> None:
    """:func:`langenv.env_kernels.run` for one session (``s``: its
    :data:`~langenv.env_kernels.SESSION` row, ``c``: its :data:`CONTROL` row)."""
    done, answer, code = ek.run(s, c[_C.p_cmd], c[_C.a_cmd], int(c[_C.left]))
    c[_C.left] -= done
    c[_C.answer] = answer
    c[_C.code] = code


@numba.njit(cache=True, nogil=True, parallel=True, error_model="numpy")
def run_parallel(sessions: np.ndarray, control: np.ndarray) -> None:
    """:func:`langenv.env_kernels.run` for every session whose control row is ``active``,
    spread over Numba's threads (``prange``); each session runs until its step's ticks are done
    or it needs Python (its answer in its control row)."""
    for i in numba.prange(sessions.shape[0]):
        if control[i, _C.active] != 0.0:
            _run_one(sessions[i], control[i])


@numba.njit(cache=True, nogil=True, error_model="numpy")
def run_serial(sessions: np.ndarray, control: np.ndarray, which: np.ndarray) -> None:
    """:func:`run_parallel` for the sessions ``which`` (int64 indexes), one after another in
    the calling thread (without the GIL: a thread pool's workers may call it together on
    disjoint sessions)."""
    for k in range(which.shape[0]):
        i = which[k]
        if control[i, _C.active] != 0.0:
            _run_one(sessions[i], control[i])


@jit
def begin(
    sessions: np.ndarray,
    control: np.ndarray,
    actions: np.ndarray,
    pause_factor: np.ndarray,
    ticks: int,
    c_min: float,
) -> None:
    """Start a step of every active session: its pace commands from ``actions`` (float64, the
    env's map :func:`~langenv.control.pacing.command_from_action`), its ticks, the pause rule's
    factor, and the step's integrals and highest speed at 0."""
    for i in range(sessions.shape[0]):
        c = control[i]
        if c[_C.active] == 0.0:
            continue
        c[_C.p_cmd] = command(actions[i, 0], c[_C.p_max], c_min)
        c[_C.a_cmd] = command(actions[i, 1], c[_C.a_max], c_min)
        c[_C.left] = ticks
        es = f8(sessions[i], _S.es)
        es[_E.em_int] = 0.0
        es[_E.pace_int] = 0.0
        es[_E.max_speed] = 0.0
        es[_E.pause_factor] = pause_factor[i]


@jit
def observe(
    sessions: np.ndarray,
    control: np.ndarray,
    which: np.ndarray,
    obs: np.ndarray,
    info: np.ndarray,
    ticks: int,
    t_scale: float,
) -> None:
    """The observation (``obs[i]``, float32) and the info values (``info[i]``, :data:`INFO`) of
    the sessions ``which`` after their step, as ``LangCtrlEnv`` computes them (its
    ``_observation``, ``_info`` and ``_step_result`` without the end's ``reward_am``)."""
    for k in range(which.shape[0]):
        i = which[k]
        s, c = sessions[i], control[i]
        ws, es, hist = f8(s, _S.ws), f8(s, _S.es), f8(s, _S.hist)
        kid_ptr, dur = i8(s, _S.kid_ptr), f8(s, _S.dur)
        n_v = dur.shape[0]
        tails = f4_2(s, _S.tails, s[_S.tails_n] // (n_v + 1))
        t_x, t_a, p, a = es[_E.t_h], es[_E.t_a], es[_E.p], es[_E.a]
        coop = ws[_T.c]
        ci = int(es[_E.coop_i])
        n = hist.shape[0]
        newest = hist[(ci - 1) % n]
        oldest = hist[ci % n] if ci >= n else 1.0
        progress = ws[_T.s] / c[_C.length]
        u = int(es[_E.phrase])
        in_pause = es[_E.in_pause] != 0.0
        pos = es[_E.speech_pos]
        if u < 0:
            said, left, due = 1.0, 0.0, False
        else:
            said = 1.0 if in_pause else min(1.0, pos / dur[u])
            left = es[_E.slot] - pos
            due = kid_ptr[u + 1] > kid_ptr[u] and es[_E.slot] - pos <= a * (ticks * es[_E.dt])
        motion_done = not math.isnan(ws[_T.t_end])
        ok.encode(
            obs[i], t_x, t_a, p, a, coop, (newest - oldest) / TREND_WINDOW, progress,
            ws[_T.hand_speed], said, left, in_pause, u < 0, motion_done, due, es[_E.time],
            tails[u if u >= 0 else n_v],
        )  # fmt: skip
        r_em, r_pace = rk.step_terms(
            es[_E.em_int], es[_E.pace_int], c[_C.w_em], c[_C.w_pace], t_scale
        )
        row = info[i]
        row[0], row[1], row[2], row[3] = es[_E.time], t_x, t_a, t_a - t_x
        row[4], row[5], row[6], row[7] = p, a, coop, ws[_T.hand_speed]
        row[8] = progress
        row[9] = 1.0 if in_pause else 0.0
        row[10] = 1.0 if motion_done else 0.0
        row[11] = 1.0 if u < 0 else 0.0
        row[12] = ws[_T.t_end]
        row[13] = c[_C.t_speech]
        row[14], row[15] = ws[_T.path_deviation], es[_E.max_speed]
        row[16], row[17] = r_em, r_pace
        row[18] = rk.total(r_em, r_pace, 0.0)
        row[19] = u
        row[20] = ws[_T.leg]
    _ = _N_INFO
