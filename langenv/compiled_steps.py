""":mod:`langenv.env_kernels` bound to one ``LangCtrlEnv``: the session's record (its arrays'
addresses, :data:`~langenv.env_kernels.SESSION`), and the state handed to and from the env's
Python objects."""

from __future__ import annotations

from typing import Any

import numpy as np

from langenv import env_kernels as ek
from langenv.users import PerturbedUser, ReplayUser, SyntheticUser

__all__ = ["TABULATED_USERS", "CompiledSteps"]

TABULATED_USERS = (SyntheticUser, PerturbedUser, ReplayUser)
"""The users whose force the compiled ticks compute (a table against the motion)."""

_E = ek.ENV_STEPS.at
_LOADED = ek.ENV_STEPS.span("p", "pause_factor")
"""The state loaded from the env's Python objects in one slice: the paces, the env's times, the
timeline's state, the cooperation count, the user's table step, the pause factor."""
_NONE = np.zeros(0)
"""The episode's arrays (the cooperation history, the user's force table) until :meth:`load`."""


class CompiledSteps:
    """:func:`langenv.env_kernels.run` bound to one ``LangCtrlEnv`` (typed ``Any``:
    ``langenv.env`` imports this module): the session's record, built once (:attr:`record`),
    and its state loaded into ``es`` before the ticks and handed back after them. The single
    env and a batch (:mod:`langenv.batch`, whose table holds a copy of each session's record)
    run the same kernels on it.

    The compiled ticks apply when the motion's tick is compiled and running, the user is one of
    :data:`TABULATED_USERS` (a tabulated force against the motion), the force sensor has no
    noise (its draws stay in Python) and the arm's joints are the model's (:meth:`usable`);
    otherwise the env ticks in Python.

    Args:
        env: The env.

    Attributes:
        order: The phrase graph's vertices in the record's order (``es[phrase]`` indexes it).
        es: The env's ticks' array (:data:`~langenv.env_kernels.ENV_STEPS`).
        named: The record's arrays by name (kept alive here while their addresses are used).
        record: The session's row of :data:`~langenv.env_kernels.SESSION`.
    """

    def __init__(self, env: Any) -> None:
        self.env = env
        graph = env.speech.graph
        self.order: tuple[str, ...] = tuple(graph.phrases)
        self.index = {u: i for i, u in enumerate(self.order)}
        mid, slot, kid_ptr, kids = graph.packed(self.order)
        lg = env.leg_plan.packed(
            [graph.segment(u) for u in self.order],
            [graph.is_gate(u) for u in self.order],
        )
        self.es = ek.ENV_STEPS.zeros()
        ek.ENV_STEPS.pack(self.es, {**env.paces.limits.settings(), "dt": env.dt})
        self.named: dict[str, np.ndarray] = {
            **env.motion.compiled_tick.named, "es": self.es, "hist": _NONE, "table": _NONE,
            "mid": mid, "slot": slot, "kid_ptr": kid_ptr,
            "kids": kids, "lg": lg, "tails": env.observation_tails(self.order),
            "dur": np.array([graph.duration[u] for u in self.order], dtype=np.float64),
        }  # fmt: skip
        self.record = ek.SESSION.pack(ek.SESSION.zeros(), self.named)  # the episode's: load

    def usable(self) -> bool:
        """Whether the compiled ticks apply now (see the class docstring)."""
        m = self.env.motion
        tick = m.compiled_tick
        return (
            tick is not None
            and m.safety_stop is None
            and tick.full_dofs
            and not m.sensor.noise_std > 0.0
            and type(self.env.user) in TABULATED_USERS
        )

    def run(
        self, p_cmd: float, a_cmd: float, n: int, em_int: float, pace_int: float
    ) -> tuple[int, int, int, float, float]:
        """Up to ``n`` ticks (:func:`~langenv.env_kernels.run`); returns its answer and the
        reward integrals."""
        self.load(em_int, pace_int)
        done, answer, code = ek.run(self.record, p_cmd, a_cmd, n)
        if done:
            em_int, pace_int = self.store()
        return done, answer, code, em_int, pace_int

    def run_law(
        self, law: np.ndarray, rows: np.ndarray, rewards: np.ndarray
    ) -> tuple[int, int, int, float, float]:
        """:func:`~langenv.env_kernels.run_law` from the env's state, handed back after it;
        returns its answer and the reward integrals of the tick that stopped the run."""
        self.load(0.0, 0.0)
        done, answer, code = ek.run_law(self.record, law, rows, rewards)
        em_int, pace_int = 0.0, 0.0
        if done or answer != ek.R_PYTHON:  # some tick ran
            em_int, pace_int = self.store()
        return done, answer, code, em_int, pace_int

    def load(self, em_int: float, pace_int: float) -> None:
        """The env's state into ``es`` (before compiled ticks), and the episode's arrays into
        the record where a reset made new ones."""
        env = self.env
        paces, speech = env.paces, env.speech
        table, step = env.user.force_table()
        hist = env.coop_history
        named = self.named
        if table is not named["table"] or hist is not named["hist"]:
            named["table"], named["hist"] = table, hist
            ek.SESSION.pack(self.record, named)
        u = speech.phrase
        pos, t, a, mark, slot, in_pause = speech.state_values()
        self.es[_LOADED] = (
            paces.p, paces.a, paces.p_dot, env.time, env.t_a, env.t_h, em_int, pace_int,
            env.max_speed,
            pos, t, a, mark, -1.0 if u is None else self.index[u], slot, in_pause,
            env.coop_index, step, env.pause_factor,
        )  # fmt: skip

    def store(self) -> tuple[float, float]:
        """``es`` back into the env's state (after compiled ticks); returns the reward
        integrals."""
        env, es = self.env, self.es
        paces, motion = env.paces, env.motion
        (
            paces.p, paces.a, paces.p_dot, time, t_a, t_h, em_int, pace_int, max_speed,
            pos, t, sa, mark, _, slot, _, coop_i, _, _,
        ) = es[_LOADED].tolist()  # fmt: skip
        env.speech.take_state(pos, t, sa, mark, slot)
        env.take_times(time, t_a, t_h, max_speed, int(coop_i))
        motion.f_user = es[_E.f_user : _E.f_user + 3].copy()
        motion.compiled_tick.sync()
        return em_int, pace_int
