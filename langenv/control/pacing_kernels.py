"""The pace laws compiled (:mod:`langenv.control.pacing`): the actuator's first-order laws
(:meth:`PaceActuator.step <langenv.control.pacing.PaceActuator.step>`), the action map
(:func:`command_from_action`, :func:`action_from_command`), the paper's aligner
(:func:`optimal_paces`, :func:`audio_command`, :func:`misalignment_feedback`,
:func:`aligner_commands`: the Python functions of the same names) and the aligner as a
:class:`~langenv.control.pacing.PaceLaw` decides it every tick from the observation
(:func:`law_commands`). The same operations in the same order (``tests/test_law_homes.py``,
``tests/test_pace_law.py``, ``tests/test_compiled_steps.py``); other packages' kernels
(:mod:`policies.residual_kernels`) call these instead of writing the law again."""

from __future__ import annotations

import numpy as np

from langenv.kernels import inline, kernel

__all__ = [
    "action",
    "action_from_command",
    "aligner_commands",
    "audio_command",
    "bounded",
    "command_from_action",
    "law_commands",
    "misalignment_feedback",
    "optimal_paces",
    "seconds_seen",
    "step",
    "stored",
]


@inline
def bounded(x: float, lo: float, hi: float) -> float:
    """Python's ``min(hi, max(lo, x))``."""
    x = x if x > lo else lo
    return x if x < hi else hi


@inline
def step(
    p: float,
    a: float,
    p_cmd: float,
    a_cmd: float,
    dt: float,
    k_p: float,
    k_a: float,
    p_min: float,
    p_max: float,
    a_min: float,
    a_max: float,
) -> tuple[float, float, float]:
    """:meth:`PaceActuator.step <langenv.control.pacing.PaceActuator.step>`: ``(p, p_dot, a)``
    after a tick."""
    p_new = bounded(p + dt * k_p * (p_cmd - p), p_min, p_max)
    p_dot = (p_new - p) / dt
    a = bounded(a + dt * k_a * (a_cmd - a), a_min, a_max)
    return p_new, p_dot, a


@kernel
def stored(v: float) -> float:
    """``v`` as the observation stores it: clipped to [-1, 1] as
    :class:`~langenv.task.observation.ObservationEncoder` clips (NaN stays NaN), rounded to
    float32."""
    v = v if -1.0 <= v <= 1.0 else (1.0 if v > 1.0 else (-1.0 if v < -1.0 else v))
    return float(np.float32(v))


@kernel
def seconds_seen(t: float, t_scale: float) -> float:
    """A time as a policy reads it back from the observation: ``t / T`` stored, times ``T``;
    negative readings as 0 (the policy's ``max(0, .)``)."""
    x = stored(t / t_scale) * t_scale
    return x if x > 0.0 else 0.0


@inline
def action_from_command(cmd: float, upper: float, c_min: float) -> float:
    """:func:`~langenv.control.pacing.action_from_command` (``c_min``: the command at ``u =
    -1``, :data:`~langenv.control.pacing.COMMAND_MIN`)."""
    u = (cmd - 1.0) / (upper - 1.0) if cmd >= 1.0 else (cmd - 1.0) / (1.0 - c_min)
    u = u if u > -1.0 else -1.0
    return u if u < 1.0 else 1.0


@kernel
def action(cmd: float, upper: float, c_min: float) -> float:
    """:func:`action_from_command`, rounded to float32 as the action stores it."""
    return float(np.float32(action_from_command(cmd, upper, c_min)))


@inline
def command_from_action(u: float, upper: float, c_min: float) -> float:
    """:func:`~langenv.control.pacing.command_from_action`."""
    if u >= 0.0:
        return 1.0 + (upper - 1.0) * u
    return 1.0 + (1.0 - c_min) * u


@inline
def optimal_paces(t_x: float, t_a: float) -> tuple[float, float]:
    """:func:`~langenv.control.pacing.optimal_paces` (``t_x, t_a >= 0``, not checked)."""
    if t_a == 0.0:
        return 1.0, 1.0
    s = t_x / t_a
    den = s * s + 1.0
    return (s * s + s) / den, (s + 1.0) / den


@inline
def audio_command(a_star: float, cooperation: float, k_ca: float) -> float:
    """:func:`~langenv.control.pacing.audio_command` (``k_ca``: the gains' ``k_c / k_a``)."""
    return a_star - k_ca * (1.0 - cooperation)


@inline
def misalignment_feedback(t_x: float, t_a: float, k_em: float, em_clip: float) -> float:
    """:func:`~langenv.control.pacing.misalignment_feedback`."""
    e = k_em * (t_a - t_x)
    e = e if e > -em_clip else -em_clip
    return e if e < em_clip else em_clip


@inline
def aligner_commands(
    t_x: float,
    t_a: float,
    cooperation: float,
    k_ca: float,
    k_em: float,
    em_clip: float,
    motion_on: bool,
) -> tuple[float, float]:
    """:func:`~langenv.control.pacing.aligner_commands` (``k_ca``: the gains' ``k_c / k_a``)."""
    p_star, a_star = optimal_paces(t_x, t_a)
    a_cmd = audio_command(a_star, cooperation, k_ca)
    if k_em > 0.0 and motion_on:
        p_star -= misalignment_feedback(t_x, t_a, k_em, em_clip)
    return p_star, a_cmd


@kernel
def law_commands(
    k_ca: float,
    k_em: float,
    em_clip: float,
    law_p_max: float,
    law_a_max: float,
    c_min: float,
    t_scale: float,
    p_max: float,
    a_max: float,
    t_x: float,
    t_a: float,
    c: float,
    motion_on: bool,
) -> tuple[float, float]:
    """The env's pace commands ``(p_cmd, a_cmd)`` for the state ``t_x``, ``t_a``, ``c``: the
    observation, :class:`~langenv.control.pacing.PaceLaw`'s law and the action as a policy at 500 Hz
    sees, decides and sends them (``p_max``, ``a_max``: the env's bounds)."""
    t_x = seconds_seen(t_x, t_scale)
    t_a = seconds_seen(t_a, t_scale)
    c = 0.5 * (stored(2.0 * c - 1.0) + 1.0)
    p_star, a_cmd = aligner_commands(t_x, t_a, c, k_ca, k_em, em_clip, motion_on)
    u_p = action(p_star, law_p_max, c_min)
    u_a = action(a_cmd, law_a_max, c_min)
    return command_from_action(u_p, p_max, c_min), command_from_action(u_a, a_max, c_min)
