"""The paper's aligner law decided every tick inside the compiled ticks (:meth:`LangCtrlEnv.run_law
<langenv.env.LangCtrlEnv.run_law>`).

At 500 Hz an analytic aligner (LC, LC-noAP) takes one env step per tick, and the Python around
each tick (observation, policy, info, the return to Python) costs several times the tick. When
the policy is exactly the law of :class:`~langenv.pacing.PaceLaw`, :func:`run_law` repeats, tick
after tick and without leaving compiled code, what the policy and the env do for one step: the
observation's fields the law reads rounded to float32 as the observation stores them, the law,
the action rounded to float32, the env's map from action to pace commands, then
:func:`langenv.kernels.steps.run` for one tick, and the step's reward and the info values the
episode log keeps. The same operations in the same order, so episodes are bit-identical to the
policy stepping the env (``tests/test_pace_law.py``).
"""

from __future__ import annotations

import math

import numpy as np

from langenv.kernels import kernel
from langenv.kernels import steps as sk
from langenv.kernels import tick as tk

__all__ = ["ROW_FIELDS", "commands", "run", "run_law"]

# law settings (``LangCtrlEnv._law_array``)
L_KCA, L_KEM, L_EMCLIP, L_PMAX, L_AMAX, L_WEM, L_WPACE, L_TSCALE, L_CMIN = range(9)
N_LAW = 9

ROW_FIELDS = (
    "time", "cooperation", "hand_speed", "p", "a", "t_x", "t_a", "em", "motion_done",
    "speech_done",
)  # fmt: skip
"""The info values :func:`run_law` records after each step, in its rows' first columns (then the
joint positions and the person's force)."""


@kernel
def _stored(v: float) -> float:
    """``v`` as the observation stores it: clipped to [-1, 1] as
    :class:`~langenv.observation.ObservationEncoder` clips (NaN stays NaN), rounded to float32."""
    v = v if -1.0 <= v <= 1.0 else (1.0 if v > 1.0 else (-1.0 if v < -1.0 else v))
    return float(np.float32(v))


@kernel
def _seconds_seen(t: float, t_scale: float) -> float:
    """A time as a policy reads it back from the observation: ``t / T`` stored, times ``T``;
    negative readings as 0 (the policy's ``max(0, .)``)."""
    x = _stored(t / t_scale) * t_scale
    return x if x > 0.0 else 0.0


@kernel
def _action(cmd: float, upper: float, c_min: float) -> float:
    """:func:`~langenv.pacing.action_from_command`, rounded to float32 as the action stores it."""
    u = (cmd - 1.0) / (upper - 1.0) if cmd >= 1.0 else (cmd - 1.0) / (1.0 - c_min)
    u = u if u > -1.0 else -1.0
    u = u if u < 1.0 else 1.0
    return float(np.float32(u))


@kernel
def _command(u: float, upper: float, c_min: float) -> float:
    """:func:`~langenv.pacing.command_from_action`."""
    if u >= 0.0:
        return 1.0 + (upper - 1.0) * u
    return 1.0 + (1.0 - c_min) * u


@kernel
def commands(
    law: np.ndarray, es: np.ndarray, t_x: float, t_a: float, c: float, motion_on: bool
) -> tuple[float, float]:
    """The env's pace commands ``(p_cmd, a_cmd)`` for the state ``t_x``, ``t_a``, ``c``: the
    observation, :class:`~langenv.pacing.PaceLaw`'s law and the action as a policy at 500 Hz
    sees, decides and sends them."""
    ts = law[L_TSCALE]
    t_x = _seconds_seen(t_x, ts)
    t_a = _seconds_seen(t_a, ts)
    c = 0.5 * (_stored(2.0 * c - 1.0) + 1.0)
    if t_a == 0.0:
        p_star, a_star = 1.0, 1.0
    else:
        s = t_x / t_a
        den = s * s + 1.0
        p_star, a_star = (s * s + s) / den, (s + 1.0) / den
    a_cmd = a_star - law[L_KCA] * (1.0 - c)
    if law[L_KEM] > 0.0 and motion_on:
        e = law[L_KEM] * (t_a - t_x)
        e = e if e > -law[L_EMCLIP] else -law[L_EMCLIP]
        p_star -= e if e < law[L_EMCLIP] else law[L_EMCLIP]
    cmin = law[L_CMIN]
    u_p = _action(p_star, law[L_PMAX], cmin)
    u_a = _action(a_cmd, law[L_AMAX], cmin)
    return _command(u_p, es[sk.E_PMAX], cmin), _command(u_a, es[sk.E_AMAX], cmin)


@kernel
def run_law(
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
    law: np.ndarray,
    rows: np.ndarray,
    rewards: np.ndarray,
) -> tuple[int, int, int]:
    """Up to ``rows.shape[0]`` one-tick steps of the law (the env at 500 Hz).

    Each finished step writes its info values (:data:`ROW_FIELDS`), the joint positions and the
    person's force into ``rows[k]`` and its reward into ``rewards[k]``.

    Returns:
        ``(steps finished, answer, code)``: as :func:`langenv.kernels.steps.run`'s answer for the
        tick that stopped the run; a tick ending in :data:`~langenv.kernels.steps.R_CONTROL`,
        :data:`~langenv.kernels.steps.R_STOP` or :data:`~langenv.kernels.steps.R_OVER` is done
        and its step is Python's to finish (not counted, not recorded); before
        :data:`~langenv.kernels.steps.R_PYTHON` nothing of the next step is done.
    """
    n_q = qpos.shape[0]
    t_scale = law[L_TSCALE]
    for k in range(rows.shape[0]):
        motion_on = math.isnan(ws[tk.S_TEND])
        p_cmd, a_cmd = commands(law, es, ws[tk.S_TX], es[sk.E_TA], ws[tk.S_C], motion_on)
        es[sk.E_EM] = 0.0
        es[sk.E_PACE] = 0.0
        es[sk.E_VMAX] = 0.0
        _, answer, code = sk.run(
            ws, path, aw, ai, jac, xpos, xmat, qpos, qvel, ctrl, qfrc, prm, tab, ptr, es, hist,
            table, mid, slot, kid_ptr, kids, p_cmd, a_cmd, 1,
        )  # fmt: skip
        if answer != sk.R_DONE:
            return k, answer, code
        r_em = -law[L_WEM] * es[sk.E_EM] / t_scale
        r_pace = -law[L_WPACE] * es[sk.E_PACE]
        rewards[k] = r_em + r_pace + 0.0
        row = rows[k]
        t_x, t_a = ws[tk.S_TX], es[sk.E_TA]
        row[0], row[1], row[2] = es[sk.E_TIME], ws[tk.S_C], ws[tk.S_HS]
        row[3], row[4], row[5], row[6] = es[sk.E_P], es[sk.E_A], t_x, t_a
        row[7] = t_a - t_x
        row[8] = 0.0 if math.isnan(ws[tk.S_TEND]) else 1.0
        row[9] = 1.0 if es[sk.E_U] < 0.0 else 0.0
        for j in range(n_q):
            row[10 + j] = qpos[j]
        for j in range(3):
            row[10 + n_q + j] = es[sk.E_F + j]
    return rows.shape[0], sk.R_DONE, 0


def run(
    steps: sk.CompiledSteps, law: np.ndarray, rows: np.ndarray, rewards: np.ndarray
) -> tuple[int, int, int, float, float]:
    """:func:`run_law` on ``steps``' env: its state loaded before and stored after; returns the
    answer and the reward integrals of the tick that stopped the run."""
    args = (*steps.load(0.0, 0.0), law, rows, rewards)
    done, answer, code = run_law(*args)
    em_int, pace_int = 0.0, 0.0
    if done or answer != sk.R_PYTHON:  # some tick ran
        em_int, pace_int = steps.store()
    return done, answer, code, em_int, pace_int
