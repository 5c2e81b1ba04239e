"""The pace laws compiled (:mod:`langenv.control.pacing`): the actuator's first-order laws
(:meth:`PaceActuator.step <langenv.control.pacing.PaceActuator.step>`), the action map
(:func:`~langenv.control.pacing.command_from_action`,
:func:`~langenv.control.pacing.action_from_command`) and
the paper's aligner as a :class:`~langenv.control.pacing.PaceLaw` decides it every tick from the
observation. The same operations in the same order (``tests/test_pace_law.py``,
``tests/test_compiled_steps.py``)."""

from __future__ import annotations

import numpy as np

from langenv.kernels import inline, kernel

__all__ = ["action", "bounded", "command", "law_commands", "seconds_seen", "step", "stored"]


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


@kernel
def action(cmd: float, upper: float, c_min: float) -> float:
    """:func:`~langenv.control.pacing.action_from_command`, rounded to float32 as the action
    stores it."""
    u = (cmd - 1.0) / (upper - 1.0) if cmd >= 1.0 else (cmd - 1.0) / (1.0 - c_min)
    u = u if u > -1.0 else -1.0
    u = u if u < 1.0 else 1.0
    return float(np.float32(u))


@inline
def command(u: float, upper: float, c_min: float) -> float:
    """:func:`~langenv.control.pacing.command_from_action`."""
    if u >= 0.0:
        return 1.0 + (upper - 1.0) * u
    return 1.0 + (1.0 - c_min) * u


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
    if t_a == 0.0:
        p_star, a_star = 1.0, 1.0
    else:
        s = t_x / t_a
        den = s * s + 1.0
        p_star, a_star = (s * s + s) / den, (s + 1.0) / den
    a_cmd = a_star - k_ca * (1.0 - c)
    if k_em > 0.0 and motion_on:
        e = k_em * (t_a - t_x)
        e = e if e > -em_clip else -em_clip
        p_star -= e if e < em_clip else em_clip
    u_p = action(p_star, law_p_max, c_min)
    u_a = action(a_cmd, law_a_max, c_min)
    return command(u_p, p_max, c_min), command(u_a, a_max, c_min)
