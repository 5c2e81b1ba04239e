""":mod:`langenv.env_kernels` bound to one ``LangCtrlEnv``: the session's record (its arrays'
addresses, :data:`~langenv.env_kernels.SESSION`), and the state handed to and from the env's
Python objects."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from langenv import env_kernels as ek
from langenv.control.pacing import PaceLaw
from langenv.errors import ConfigError
from langenv.robot.arm import Arm
from langenv.task.observation import T_SCALE
from langenv.users import PerturbedUser, ReplayUser, SyntheticUser

__all__ = ["LAW_CHUNK", "TABULATED_USERS", "CompiledSteps", "LawSteps", "run_law"]

TABULATED_USERS = (SyntheticUser, PerturbedUser, ReplayUser)
"""The users whose force the compiled ticks compute (a table against the motion)."""

_E = ek.ENV_STEPS.at
_LOADED = ek.ENV_STEPS.span("p", "reopen_at")
"""The state loaded from the env's Python objects in one slice: the paces, the env's times, the
timeline's state, the cooperation count, the user's table step, the pause factor, from when the
speech may go on after its end."""
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
            env.coop_index, step, env.pause_factor, env.reopen_at,
        )  # fmt: skip

    def store(self) -> tuple[float, float]:
        """``es`` back into the env's state (after compiled ticks); returns the reward
        integrals."""
        env, es = self.env, self.es
        paces, motion = env.paces, env.motion
        (
            paces.p, paces.a, paces.p_dot, time, t_a, t_h, em_int, pace_int, max_speed,
            pos, t, sa, mark, _, slot, _, coop_i, _, _, _,
        ) = es[_LOADED].tolist()  # fmt: skip
        env.speech.take_state(pos, t, sa, mark, slot)
        env.take_times(time, t_a, t_h, max_speed, int(coop_i))
        motion.f_user = es[_E.f_user : _E.f_user + 3].copy()
        motion.compiled_tick.sync()
        return em_int, pace_int


LAW_CHUNK = 4096
"""Most steps one :meth:`LangCtrlEnv.run_law` call takes (8 s at 500 Hz; its arrays ~0.6 MB)."""


@dataclass(frozen=True)
class LawSteps:
    """Steps taken by :meth:`LangCtrlEnv.run_law`.

    Attributes:
        steps: Steps finished in compiled code (not counting ``last``'s).
        info: Per step (``steps`` rows) the info values ``time``, ``cooperation``,
            ``hand_speed``, ``p``, ``a``, ``t_x``, ``t_a``, ``em``, ``motion_done`` and
            ``speech_done`` (these two as 0/1), ``leg`` (the leg's index), the joint positions
            ``qpos`` (rad, shape ``(steps, nq)``) and the person's force ``f_user`` (N, shape
            ``(steps, 3)``).
        rewards: Each step's reward, shape ``(steps,)``.
        phrase: The phrase (``info["phrase"]``) during these steps (they never cross a boundary).
        in_pause: Whether these steps lie in the pause after it.
        last: ``(observation, reward, terminated, truncated, info)`` of one more step the law
            took and Python finished (the episode's end, a protective stop, joint-limit
            avoidance), or None.
    """

    steps: int
    info: dict[str, np.ndarray]
    rewards: np.ndarray
    phrase: str | None
    in_pause: bool
    last: tuple[np.ndarray, float, bool, bool, dict[str, Any]] | None


def run_law(env: Any, law: PaceLaw, max_steps: int) -> LawSteps:
    """:meth:`LangCtrlEnv.run_law <langenv.env.LangCtrlEnv.run_law>` (see there), through the
    env's hooks for a batch."""
    if env.ticks_per_step != 1:
        raise ConfigError(
            f"run_law needs decision_hz=500 (one tick per step), got {env.decision_hz}"
        )
    if not isinstance(law, PaceLaw):
        raise ConfigError(f"law must be a PaceLaw, got {type(law).__name__}")
    if isinstance(max_steps, bool) or not isinstance(max_steps, int | np.integer):
        raise ConfigError(f"max_steps must be an integer, got {max_steps!r}")
    if max_steps < 0:
        raise ConfigError(f"max_steps must be >= 0, got {max_steps}")
    arm = env.motion.arm
    n_q = arm.data.qpos.shape[0] if isinstance(arm, Arm) else 0
    n = _law_steps_left(env, max_steps)
    rows = np.zeros((n, len(ek.ROW_FIELDS) + n_q + 3))
    rewards = np.zeros(n)
    phrase, in_pause = env.speech.phrase, env.speech.in_pause
    done, last = 0, None
    steps = env.compiled_steps
    if n and steps is not None:
        env.take_choice([0.0] * (env.action_space.shape[0] - 2))  # the law's phrase rule
        done, answer, code, em_int, pace_int = steps.run_law(_law_array(env, law), rows, rewards)
        if answer not in (ek.R_DONE, ek.R_PYTHON):  # a tick ended as only Python can
            em, pace, _ = env.finish_event(answer, code, 0.0, 0.0)
            last = env.step_result(em_int + em * env.dt, pace_int + pace * env.dt)
    k = len(ek.ROW_FIELDS)
    info = {name: rows[:done, j] for j, name in enumerate(ek.ROW_FIELDS)}
    info["qpos"], info["f_user"] = rows[:done, k : k + n_q], rows[:done, k + n_q :]
    return LawSteps(done, info, rewards[:done], phrase, in_pause, last)


def _law_steps_left(env: Any, max_steps: int) -> int:
    """Steps :func:`run_law` may take: at most ``max_steps`` and :data:`LAW_CHUNK`, and one
    fewer than the steps left to the session's length (that last step is Python's)."""
    n = min(int(max_steps), LAW_CHUNK)
    if env.ticks_left is not None:
        n = min(n, env.ticks_left - 1)
    return max(0, n) if env.runs_compiled else 0


def _law_array(env: Any, law: PaceLaw) -> np.ndarray:
    """``law`` and the reward weights as :func:`langenv.env_kernels.run_law` reads them
    (:data:`~langenv.env_kernels.LAW`)."""
    weights = {"w_em": env.w_em, "w_pace": env.w_pace, "t_scale": T_SCALE}
    return ek.LAW.pack_all(ek.LAW.zeros(), law.values(), weights)
