""":class:`~policies.learned.ResidualLC` for a batch of sessions, compiled: the same features and
the same actions, bit for bit (``tests/test_train_batched.py``), at a fraction of a
microsecond per session instead of tens.

The Python class keeps its state in attributes (the base LC's motion-rate estimate, the
features' averages, the last correction); here each session's state is a row of
:data:`RESIDUAL_STATE` and its latest observation a row of ``last_obs``; the design
(:class:`~policies.learned.ResidualSpec`, the pace limits and the base's gains) is a row of
:data:`RESIDUAL_PARAMS` (:func:`residual_params`). :func:`observe` takes a batch of observations
(``start``: a session's first of an episode) and writes the augmented ones; :func:`act` maps a
batch of corrections to the env's actions for the latest observations.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

import langenv
from langenv.control.pacing import COMMAND_MIN, AlignerGains, PaceLimits
from langenv.control.pacing_kernels import (
    action_from_command,
    aligner_commands,
    command_from_action,
)
from langenv.kernels import SOURCES, clear_stale_cache, inline, jit
from langenv.layout import Layout, field_table
from langenv.task.observation import (
    CHILD_FIELDS,
    ELAPSED_SCALE,
    FIRST_CHILD,
    PACE_SCALE,
    T_SCALE,
    Obs,
)
from policies.analytic import NEW_HORIZON, RATE_FLOOR, RATE_TAU
from policies.learned import FINE_SCALE, LOST_SCALE, PRIOR_SCALE, RATE_AVG_TAU

__all__ = ["RESIDUAL_PARAMS", "RESIDUAL_STATE", "act", "observe", "residual_params"]

_LANGENV = Path(langenv.__file__).resolve().parent
clear_stale_cache(  # numba checks this file only; the kernels read langenv's declarations and
    # kernels and the constants of the Python references (analytic.py, learned.py)
    Path(__file__).resolve().parent,
    (
        "residual_kernels.py",
        "analytic.py",
        "learned.py",
        *(str(_LANGENV / name) for name in SOURCES),
    ),
    ("residual_kernels.py",),
    stamp=".",
)

RESIDUAL_STATE = Layout(
    "residual_state",
    field_table(
        """
        t_x0              t_x at the episode's start (s)
        rate              the motion-rate feature
        rate_avg          its average
        last_r_p          the previous correction of p, as applied
        last_r_a          the previous correction of a, as applied
        base_final:bool   the base is in its terminal or finishing phase
        base_p            the base's physical pace action for the latest observation
        base_a            the base's audio pace action
        lc_has_last:bool  the base's rate estimate has a previous sample
        lc_last_t_x       its t_x (s)
        lc_last_now       its time (s)
        lc_rate           the base's motion-rate estimate (1 at rest)
        """
    ),
)
"""One session's state of :class:`~policies.learned.ResidualLC` (and of its base
:class:`~policies.analytic.LanguageController`)."""
RESIDUAL_PARAMS = Layout(
    "residual_params",
    field_table(
        """
        scores:bool       choice_mode 'scores' (else 'target')
        max_children:int  choice scores
        pace_scale        largest change of the p command
        audio_gain        largest change of the a command
        choice_scale      largest change of the choice
        decision_hz       decision rate (1/s)
        terminal          the base's terminal-phase horizon (s)
        k_em              the base's misalignment feedback (1/s)
        em_clip           its bound
        gate_em           the correction's gate (s)
        deadband          the correction's dead band
        p_max             the pace limits' upper bound of p
        a_max             and of a
        k_ca              the base's k_c / k_a
        """
    ),
)
"""The design of the correction and of its base, as the kernels read it."""

# Numba's ``float(x)`` of a float32 is a float32: the observation's entries are widened with
# ``np.float64`` (what Python's ``float`` gives), so that arithmetic on them is float64's.
_S = RESIDUAL_STATE.at
_P = RESIDUAL_PARAMS.at
_N_FEATURES = 9
_TX, _TA, _P_, _A_ = int(Obs.T_X), int(Obs.T_A), int(Obs.P), int(Obs.A)
_COOP, _MDONE, _SDONE, _ELAPSED = (
    int(Obs.COOPERATION),
    int(Obs.MOTION_DONE),
    int(Obs.SPEECH_DONE),
    int(Obs.ELAPSED),
)


def residual_params(spec: object, limits: PaceLimits | None = None) -> np.ndarray:
    """:data:`RESIDUAL_PARAMS` of a :class:`~policies.learned.ResidualSpec` (its base: the
    default gains and ``em_clip``, as :class:`~policies.learned.ResidualLC` builds it)."""
    from policies.analytic import LanguageController

    lim = limits if limits is not None else PaceLimits()
    base = LanguageController(limits=lim)
    gains = AlignerGains()
    s: object = spec
    return RESIDUAL_PARAMS.pack_all(
        RESIDUAL_PARAMS.zeros(),
        {
            "scores": s.choice_mode == "scores",  # type: ignore[attr-defined]
            "max_children": s.max_children,  # type: ignore[attr-defined]
            "pace_scale": s.pace_scale,  # type: ignore[attr-defined]
            "audio_gain": s.audio_gain,  # type: ignore[attr-defined]
            "choice_scale": s.choice_scale,  # type: ignore[attr-defined]
            "decision_hz": s.decision_hz,  # type: ignore[attr-defined]
            "terminal": s.terminal,  # type: ignore[attr-defined]
            "k_em": s.k_em,  # type: ignore[attr-defined]
            "em_clip": base.em_clip,
            "gate_em": s.gate_em,  # type: ignore[attr-defined]
            "deadband": s.deadband,  # type: ignore[attr-defined]
            "p_max": lim.p_max,
            "a_max": lim.a_max,
            "k_ca": gains.k_c / gains.k_a,
        },
    )


@inline
def _wide(x: float) -> float:
    """An observation's entry as a float64 (Python's ``float``; see the comment at ``_S``)."""
    return np.float64(x)


@inline
def _pmax0(x: float) -> float:
    """Python's ``max(0.0, x)``."""
    return x if x > 0.0 else 0.0


@inline
def _clip1(x: float) -> float:
    """Python's ``min(1.0, max(-1.0, x))``."""
    x = x if x > -1.0 else -1.0
    return x if x < 1.0 else 1.0


@inline
def _phase(o: np.ndarray, terminal: float) -> int:
    """``LanguageController.phase``: 0 aligning, 1 terminal, 2 finishing, 3 over."""
    motion_done = o[_MDONE] > 0.0
    speech_done = o[_SDONE] > 0.0
    if motion_done and speech_done:
        return 3
    if terminal <= 0.0:
        return 0
    if motion_done or speech_done:
        return 2
    t_x = _wide(o[_TX]) * T_SCALE
    return 1 if t_x < terminal else 0


@jit
def _base_act(o: np.ndarray, st: np.ndarray, prm: np.ndarray) -> None:
    """``LanguageController.act`` on the observation ``o``: its action into ``st`` (float32
    values), its rate estimate updated."""
    terminal = prm[_P.terminal]
    if terminal > 0.0:  # _update_rate
        t_x = _wide(o[_TX]) * T_SCALE
        now = _wide(o[_ELAPSED]) * ELAPSED_SCALE
        if o[_MDONE] > 0.0:
            st[_S.lc_has_last] = 0.0
        else:
            skip = False
            if st[_S.lc_has_last] != 0.0:
                dt = now - st[_S.lc_last_now]
                if dt <= 0.0:
                    skip = True
                elif t_x > st[_S.lc_last_t_x] + NEW_HORIZON:
                    pass  # the next leg's horizon: not a rate (policies.analytic.NEW_HORIZON)
                else:
                    w = dt / (RATE_TAU + dt)
                    st[_S.lc_rate] += w * ((st[_S.lc_last_t_x] - t_x) / dt - st[_S.lc_rate])
            if not skip:
                st[_S.lc_has_last] = 1.0
                st[_S.lc_last_t_x] = t_x
                st[_S.lc_last_now] = now
    t_x = _pmax0(_wide(o[_TX]) * T_SCALE)
    t_a = _pmax0(_wide(o[_TA]) * T_SCALE)
    c = 0.5 * (_wide(o[_COOP]) + 1.0)
    motion_done = o[_MDONE] > 0.0
    p_star, a_cmd = aligner_commands(
        t_x, t_a, c, prm[_P.k_ca], prm[_P.k_em], prm[_P.em_clip], not motion_done
    )
    phase = _phase(o, terminal)
    if phase == 1:
        p_star = 1.0
        rate = st[_S.lc_rate]
        rate = rate if rate > RATE_FLOOR else RATE_FLOOR
        a_cmd = t_a * rate / (t_x if t_x > 1e-6 else 1e-6)
    elif phase == 2:
        if motion_done:
            a_cmd = prm[_P.a_max]
        else:
            p_star = prm[_P.p_max]
    st[_S.base_p] = np.float32(action_from_command(p_star, prm[_P.p_max], COMMAND_MIN))
    st[_S.base_a] = np.float32(action_from_command(a_cmd, prm[_P.a_max], COMMAND_MIN))


@jit
def _augment(o: np.ndarray, st: np.ndarray, prm: np.ndarray, out: np.ndarray) -> None:
    t_x = _pmax0(_wide(o[_TX]) * T_SCALE)
    t_a = _pmax0(_wide(o[_TA]) * T_SCALE)
    p = 1.0 + PACE_SCALE * _wide(o[_P_])
    a = 1.0 + PACE_SCALE * _wide(o[_A_])
    _base_act(o, st, prm)
    phase = _phase(o, prm[_P.terminal])
    st[_S.base_final] = 1.0 if (phase == 1 or phase == 2) else 0.0
    elapsed = _wide(o[_ELAPSED]) * ELAPSED_SCALE
    lost = elapsed - (st[_S.t_x0] - t_x)
    n = o.shape[0]
    for j in range(n):
        out[j] = o[j]
    feats = (
        st[_S.base_p],
        st[_S.base_a],
        (t_a / a - t_x / p) / FINE_SCALE,
        (t_a - t_x) / FINE_SCALE,
        st[_S.rate],
        st[_S.rate_avg],
        lost / LOST_SCALE,
        st[_S.last_r_p],
        st[_S.last_r_a],
    )
    for j in range(_N_FEATURES):
        v = np.float32(feats[j])
        out[n + j] = v if -1.0 <= v <= 1.0 else (1.0 if v > 1.0 else (-1.0 if v < -1.0 else v))


@jit
def observe(
    obs: np.ndarray,
    start: np.ndarray,
    last_obs: np.ndarray,
    state: np.ndarray,
    prm: np.ndarray,
    out: np.ndarray,
) -> None:
    """``ResidualLC.start`` (where ``start[i]``) or ``ResidualLC.observe`` of each session's
    observation ``obs[i]`` (float32): its augmented observation into ``out[i]`` (float32, 9
    more entries), its state and latest observation updated."""
    for i in range(obs.shape[0]):
        o, st, prev = obs[i], state[i], last_obs[i]
        if start[i]:
            st[_S.lc_has_last] = 0.0
            st[_S.lc_rate] = 1.0
            st[_S.t_x0] = _wide(o[_TX]) * T_SCALE
            st[_S.rate] = 0.0
            st[_S.rate_avg] = 0.0
            st[_S.last_r_p] = 0.0
            st[_S.last_r_a] = 0.0
        else:
            dt = (_wide(o[_ELAPSED]) - _wide(prev[_ELAPSED])) * ELAPSED_SCALE
            if dt <= 0.0:
                dt = 1.0 / prm[_P.decision_hz]
            rate = (_wide(prev[_TX]) - _wide(o[_TX])) * T_SCALE / dt - 1.0
            st[_S.rate] = _clip1(rate)
            w = 1.0 - math.exp(-dt / RATE_AVG_TAU)
            st[_S.rate_avg] += w * (st[_S.rate] - st[_S.rate_avg])
        for j in range(o.shape[0]):
            prev[j] = o[j]
        _augment(o, st, prm, out[i])


@jit
def act(
    residual: np.ndarray, last_obs: np.ndarray, state: np.ndarray, prm: np.ndarray, out: np.ndarray
) -> None:
    """``ResidualLC.action`` of each session's correction ``residual[i]`` (float64, already
    finite) for its latest observation: the env's action into ``out[i]`` (float32)."""
    dead = prm[_P.deadband]
    scores = prm[_P.scores] != 0.0
    k = residual.shape[1]
    r = np.empty(k)
    for i in range(residual.shape[0]):
        o, st = last_obs[i], state[i]
        for j in range(k):
            v = residual[i, j]
            v = v if v >= -1.0 else -1.0  # np.clip
            v = v if v <= 1.0 else 1.0
            if dead > 0.0:
                sg = 1.0 if v > 0.0 else (-1.0 if v < 0.0 else 0.0)
                m = abs(v) - dead
                v = sg * (m if m > 0.0 else 0.0) / (1.0 - dead)
            r[j] = v
        if st[_S.base_final] != 0.0:
            r[0] = 0.0
            r[1] = 0.0
        gate = prm[_P.gate_em]
        if gate > 0.0 and abs(_wide(o[_TA]) * T_SCALE - _wide(o[_TX]) * T_SCALE) < gate:
            for j in range(k):
                r[j] = 0.0
        if prm[_P.pace_scale] == 0.0:
            r[0] = 0.0
        if prm[_P.audio_gain] == 0.0:
            r[1] = 0.0
        p_max, a_max = prm[_P.p_max], prm[_P.a_max]
        p_cmd = command_from_action(st[_S.base_p], p_max, COMMAND_MIN) + prm[_P.pace_scale] * r[0]
        a_cmd = command_from_action(st[_S.base_a], a_max, COMMAND_MIN) + prm[_P.audio_gain] * r[1]
        row = out[i]
        row[0] = np.float32(action_from_command(p_cmd, p_max, COMMAND_MIN))
        row[1] = np.float32(action_from_command(a_cmd, a_max, COMMAND_MIN))
        st[_S.last_r_p] = r[0]
        st[_S.last_r_a] = r[1]
        if not scores:
            row[2] = np.float32(_clip1(prm[_P.choice_scale] * r[2]))
        else:
            t_x = _pmax0(_wide(o[_TX]) * T_SCALE)
            for c in range(int(prm[_P.max_children])):
                base = FIRST_CHILD + CHILD_FIELDS * c
                if base + 2 >= o.shape[0]:
                    break
                mid = 0.5 * (_wide(o[base + 1]) + _wide(o[base + 2])) * T_SCALE
                d = abs(t_x - mid)
                prior = (PRIOR_SCALE - d) / (PRIOR_SCALE + d)
                score = 0.5 * (prior + prm[_P.choice_scale] * r[2 + c])
                row[2 + c] = np.float32(_clip1(score))
