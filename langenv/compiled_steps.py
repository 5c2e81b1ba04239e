""":mod:`langenv.env_kernels` bound to one ``LangCtrlEnv``: its arrays, packed from the parts'
declarations, and the state handed to and from the env's Python objects."""

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


class CompiledSteps:
    """:func:`langenv.env_kernels.run` bound to one ``LangCtrlEnv`` (typed ``Any``:
    ``langenv.env`` imports this module): loads the env's state into ``es`` before the ticks and
    hands it back after them.

    The compiled ticks apply when the motion's tick is compiled and running, the user is one of
    :data:`TABULATED_USERS` (a tabulated force against the motion), the force sensor has no
    noise (its draws stay in Python) and the arm's joints are the model's (:meth:`usable`);
    otherwise the env ticks in Python.

    Args:
        env: The env.
        es: The array to keep ``es`` in (a row of a batch's, :mod:`langenv.batch`); None: a new
            one.
    """

    def __init__(self, env: Any, es: np.ndarray | None = None) -> None:
        self.env = env
        graph = env.speech.graph
        self.order: tuple[str, ...] = tuple(graph.phrases)
        self.index = {u: i for i, u in enumerate(self.order)}
        self.mid, self.slot, self.kid_ptr, self.kids = graph.packed(self.order)
        self.lg = env.leg_plan.packed(
            [graph.segment(u) for u in self.order],
            [graph.is_gate(u) for u in self.order],
        )
        self._graph = (self.mid, self.slot, self.kid_ptr, self.kids, self.lg)
        self._head: tuple[np.ndarray, ...] | None = None
        self.es = es if es is not None else ek.ENV_STEPS.zeros()
        ek.ENV_STEPS.pack(self.es, {**env.paces.limits.settings(), "dt": env.dt})

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
        args: tuple[Any, ...] = (*self.load(em_int, pace_int), p_cmd, a_cmd, n)
        done, answer, code = ek.run(*args)
        if done:
            em_int, pace_int = self.store()
        return done, answer, code, em_int, pace_int

    def run_law(
        self, law: np.ndarray, rows: np.ndarray, rewards: np.ndarray
    ) -> tuple[int, int, int, float, float]:
        """:func:`~langenv.env_kernels.run_law` from the env's state, handed back after it;
        returns its answer and the reward integrals of the tick that stopped the run."""
        args: tuple[Any, ...] = (*self.load(0.0, 0.0), law, rows, rewards)
        done, answer, code = ek.run_law(*args)
        em_int, pace_int = 0.0, 0.0
        if done or answer != ek.R_PYTHON:  # some tick ran
            em_int, pace_int = self.store()
        return done, answer, code, em_int, pace_int

    def arrays(self) -> tuple[np.ndarray, ...]:
        """The arrays :func:`~langenv.env_kernels.run` takes first (``ws`` ... ``lg``), in
        order; ``es`` as it is (see :meth:`load`)."""
        return self._arrays(self.env.user.force_table()[0])

    def _arrays(self, table: np.ndarray) -> tuple[np.ndarray, ...]:
        head = self._head
        if head is None:  # the tick's arrays and es: fixed for the env's life
            head = self._head = (*self.env.motion.compiled_tick.arrays(), self.es)
        return (*head, self.env.coop_history, table, *self._graph)

    def load(self, em_int: float, pace_int: float) -> tuple[np.ndarray, ...]:
        """The env's state into ``es`` (before compiled ticks); returns :meth:`arrays`."""
        env = self.env
        paces, speech = env.paces, env.speech
        table, step = env.user.force_table()
        u = speech.phrase
        pos, t, a, mark, slot, in_pause = speech.state_values()
        self.es[_LOADED] = (
            paces.p, paces.a, paces.p_dot, env.time, env.t_a, env.t_h, em_int, pace_int,
            env.max_speed,
            pos, t, a, mark, -1.0 if u is None else self.index[u], slot, in_pause,
            env.coop_index, step, env.pause_factor,
        )  # fmt: skip
        return self._arrays(table)

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
