"""``LangCtrl-v0`` natively vectorised: N sessions stepped in one compiled call per decision."""

from __future__ import annotations

import math
import os
from collections.abc import Sequence
from concurrent.futures import ThreadPoolExecutor
from typing import Any, Literal

import numba
import numpy as np
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from langenv import env_kernels as ek
from langenv.batch import kernels as bk
from langenv.control.pacing import COMMAND_MIN
from langenv.env import LangCtrlEnv
from langenv.errors import ActionError, ConfigError
from langenv.kernels.cores import usable_cores
from langenv.kernels.views import address
from langenv.speech.choice import duration_factor
from langenv.speech.graph import graph_path
from langenv.speech.shared import shared_graph
from langenv.task.observation import T_SCALE

__all__ = ["PARALLEL_MODES", "LangCtrlVectorEnv", "make_vector_env"]

PARALLEL_MODES = ("pool", "prange", "serial")
"""How the sessions' compiled ticks are spread over the cores: a thread pool of GIL-free calls
(the default), Numba's ``prange`` threads, or none (the calling thread)."""

_PER_SESSION = ("exercise", "phrase_graph", "users", "session")
_C = bk.CONTROL.at
CHUNK = 2
"""Sessions per share of a round in the thread pool: the threads take the next share as they
come free, so a thread the OS pauses (other programs on the cores) leaves its work to the
others instead of holding the round up."""
_INFO_COL = {name: j for j, name in enumerate(bk.INFO)}
_FLAGS = ("in_pause", "motion_done", "speech_done")


class LangCtrlVectorEnv(VectorEnv[np.ndarray, np.ndarray, np.ndarray]):
    """``num_envs`` sessions of ``LangCtrl-v0`` as one Gymnasium ``VectorEnv``, stepped in one
    compiled call per decision.

    Made by ``gym.make_vec("LangCtrl-v0", num_envs=N, vectorization_mode="vector_entry_point",
    **env_kwargs)`` (the default mode for this id). Each session is a whole
    :class:`~langenv.env.LangCtrlEnv` with its own exercise, phrase graph, user and generator;
    a step runs every session's ticks in compiled code at once (:mod:`langenv.batch.kernels`),
    spread over the cores by threads that do not hold the GIL. A session that needs Python (a
    phrase boundary: the next phrase is chosen there; a protective stop; the episode's end;
    joint-limit avoidance) has that one tick done in Python while the others wait, then joins
    the next compiled round for the rest of its step; a session whose ticks cannot be compiled
    (a callable user, sensor noise) steps in Python. Its observations, rewards and end flags are
    the single env's, bit for bit (``tests/test_batch.py``).

    Spaces: ``single_observation_space`` and ``single_action_space`` are the single env's;
    ``observation_space`` and ``action_space`` their batches (``(N, ...)``).

    **Seeding.** ``reset(seed=s)`` gives session ``i`` the episode the single env gives with
    ``reset(seed=s + i)``; a list gives each session its own; later episodes (autoreset) draw
    from each session's generator, as ``SyncVectorEnv`` does.

    **Autoreset** (``autoreset_mode``, Gymnasium's :class:`~gymnasium.vector.AutoresetMode`):
    ``NEXT_STEP`` (the default, Gymnasium's): a session that ended is reset at the next step,
    which ignores its action and returns its first observation with reward 0; ``SAME_STEP``
    (what SB3's ``VecEnv`` wants): it is reset in the step that ended it, which returns the new
    episode's first observation, the final one in ``infos["final_obs"]`` and the final info in
    ``infos["final_info"]``; ``DISABLED``: reset it yourself with
    ``reset(options={"reset_mask": mask})``.

    **Infos** are arrays, one entry per session, each with its ``_key`` mask (Gymnasium's
    convention): the single env's keys; numbers as float64 (``t_motion``, ``t_speech`` and
    ``am`` NaN where the single env has None, their masks False there), flags as bool,
    ``phrase``, ``safety_stop`` and ``safety_message`` as object arrays.

    Args:
        num_envs: Sessions, >= 1.
        max_episode_steps: Truncation after this many steps of an episode as well; None (the
            default): only at each session's length, ``max_seconds`` (60 s), as the single env.
        autoreset_mode: See above (an ``AutoresetMode`` or its value, ``"NextStep"``...).
        parallel: ``"pool"`` (a thread pool whose workers each run a share of the sessions in
            compiled code without the GIL: the default), ``"prange"`` (Numba's own threads;
            its ``workqueue`` layer unless ``NUMBA_THREADING_LAYER`` names another: OpenMP's
            spinning threads lost 3x on a machine other processes kept busy, and OpenMP does
            not survive a fork) or ``"serial"`` (the calling thread).
        threads: Threads to use (default: the cores this process may run on).
        session_kwargs: Per session, keyword arguments that differ (a sequence of ``num_envs``
            mappings), e.g. ``[{"exercise": "hand_to_mouth"}, ...]``.
        **env_kwargs: The single env's arguments, for every session. ``exercise``,
            ``phrase_graph``, ``users`` and ``session`` may also be lists: session ``i`` takes
            item ``i mod len``. Sessions whose graphs differ share one observation layout
            (``max_children``: the largest out-degree of them all).

    Raises:
        ConfigError: for a bad argument (named), or sessions whose spaces differ.
    """

    metadata: dict[str, Any] = {"autoreset_mode": AutoresetMode.NEXT_STEP, "render_modes": []}  # noqa: RUF012

    def __init__(
        self,
        num_envs: int = 1,
        *,
        max_episode_steps: int | None = None,
        autoreset_mode: AutoresetMode | str = AutoresetMode.NEXT_STEP,
        parallel: Literal["pool", "prange", "serial"] = "pool",
        threads: int | None = None,
        session_kwargs: Sequence[dict[str, Any]] | None = None,
        **env_kwargs: Any,
    ) -> None:
        if isinstance(num_envs, bool) or not isinstance(num_envs, int | np.integer) or num_envs < 1:
            raise ConfigError(f"num_envs must be an int >= 1, got {num_envs!r}")
        if max_episode_steps is not None and (
            isinstance(max_episode_steps, bool)
            or not isinstance(max_episode_steps, int | np.integer)
            or max_episode_steps < 1
        ):
            raise ConfigError(
                f"max_episode_steps must be an int >= 1 or None, got {max_episode_steps!r}"
            )
        try:
            mode = AutoresetMode(autoreset_mode)
        except ValueError:
            known = ", ".join(m.value for m in AutoresetMode)
            raise ConfigError(
                f"autoreset_mode must be one of {known}, got {autoreset_mode!r}"
            ) from None
        if parallel not in PARALLEL_MODES:
            raise ConfigError(f"parallel must be one of {PARALLEL_MODES}, got {parallel!r}")
        if parallel == "prange" and "NUMBA_THREADING_LAYER" not in os.environ:
            config: Any = numba.config  # THREADING_LAYER is not in numba's type stubs
            config.THREADING_LAYER = "workqueue"  # no effect once a layer has started
        if env_kwargs.get("render_mode") is not None:
            raise ConfigError("the batched env renders nothing: render a single LangCtrl-v0")
        env_kwargs.pop("render_mode", None)
        n = int(num_envs)
        per = _session_kwargs(n, env_kwargs, session_kwargs)
        if "max_children" not in env_kwargs:  # one observation layout for every session
            widest = max(_max_children(kw) for kw in per)
            per = [{"max_children": widest, **kw} for kw in per]
        self.num_envs = n
        self.envs: list[LangCtrlEnv] = [LangCtrlEnv(**kw) for kw in per]
        """The sessions (their Python objects are brought up to date only where Python acts;
        :meth:`sync` brings all of them)."""
        first = self.envs[0]
        for i, env in enumerate(self.envs):
            if env.observation_space != first.observation_space or (
                env.action_space != first.action_space
            ):
                raise ConfigError(
                    f"session {i}'s spaces differ from session 0's: {env.observation_space}, "
                    f"{env.action_space}"
                )
            if env.decision_hz != first.decision_hz:
                raise ConfigError("every session must decide at the same decision_hz")
        self.single_observation_space = first.observation_space
        self.single_action_space = first.action_space
        self.observation_space = batch_space(self.single_observation_space, n)
        self.action_space = batch_space(self.single_action_space, n)
        self.metadata = {**type(self).metadata, "autoreset_mode": mode}
        self.autoreset_mode = mode
        self.max_episode_steps = None if max_episode_steps is None else int(max_episode_steps)
        self.parallel = parallel
        cores = usable_cores()
        self.threads = max(1, min(int(threads) if threads else cores, cores))
        self._pool = (
            ThreadPoolExecutor(self.threads - 1)
            if parallel == "pool" and self.threads > 1
            else None
        )
        self._ticks = first.ticks_per_step
        self._sessions = np.zeros((n, bk.SESSION.size), np.int64)
        self._control = bk.CONTROL.zeros(n)
        self._keep: list[tuple[np.ndarray, ...]] = [()] * n
        self._names: list[tuple[str, ...]] = [()] * n
        self._compiled = np.zeros(n, bool)
        self._elapsed = np.zeros(n, np.int64)
        never = np.iinfo(np.int64).max // 2
        self._max_ticks = np.array(
            [e.max_ticks if e.max_ticks is not None else never for e in self.envs], np.int64
        )
        self._autoreset = np.zeros(n, bool)
        self._obs = np.zeros((n, *self.single_observation_space.shape), np.float32)  # type: ignore[misc]
        self._info = np.zeros((n, len(bk.INFO)))
        for i in range(n):
            self._bind(i)

    # ------------------------------------------------------------------ gym API
    def reset(
        self,
        *,
        seed: int | Sequence[int | None] | None = None,
        options: dict[str, Any] | None = None,
    ) -> tuple[np.ndarray, dict[str, Any]]:
        """Reset every session (or those of ``options["reset_mask"]``, a bool array); see the
        class docstring for ``seed``. Other ``options`` go to each session's reset."""
        n = self.num_envs
        if seed is None:
            seeds: list[int | None] = [None] * n
        elif isinstance(seed, int | np.integer) and not isinstance(seed, bool):
            seeds = [int(seed) + i for i in range(n)]
        else:
            seeds = list(seed)  # type: ignore[arg-type]
            if len(seeds) != n:
                raise ConfigError(f"seed: a list of {n} seeds expected, got {len(seeds)}")
        options = dict(options or {})
        mask = options.pop("reset_mask", None)
        if mask is None:
            mask = np.ones(n, bool)
        elif not (isinstance(mask, np.ndarray) and mask.dtype == np.bool_ and mask.shape == (n,)):
            raise ConfigError(f"options['reset_mask'] must be a bool array of shape ({n},)")
        infos: dict[str, Any] = {}
        for i in np.flatnonzero(mask).tolist():
            obs, info = self._reset_session(i, seeds[i], options or None)
            self._obs[i] = obs
            _add_info(infos, info, i, n)
        self._autoreset[mask] = False
        return self._obs.copy(), infos

    def step(
        self, actions: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]:
        """Step every session with its row of ``actions`` (shape ``(num_envs, *action_shape)``);
        see the class docstring for the autoreset."""
        n = self.num_envs
        act = _checked_actions(actions, (n, *self.single_action_space.shape))  # type: ignore[misc]
        rewards = np.zeros(n)
        terminated = np.zeros(n, bool)
        truncated = np.zeros(n, bool)
        infos: dict[str, Any] = {}
        resetting = (
            self._autoreset.copy()
            if self.autoreset_mode == AutoresetMode.NEXT_STEP
            else np.zeros(n, bool)
        )
        if self.autoreset_mode == AutoresetMode.DISABLED and self._autoreset.any():
            ended = np.flatnonzero(self._autoreset).tolist()
            raise ConfigError(
                f"sessions {ended} ended: reset them (options={{'reset_mask': ...}}) "
                "before stepping"
            )
        stepping = ~resetting
        compiled = stepping & self._compiled
        results: dict[int, tuple[np.ndarray, float, bool, bool, dict[str, Any]]] = {}
        for i in np.flatnonzero(stepping & ~compiled).tolist():  # sessions that tick in Python
            results[i] = self.envs[i].step(act[i])
        if compiled.any():
            self._step_compiled(act, compiled, results)
        # results, in the batch's arrays
        fast = compiled.copy()
        for i in results:
            fast[i] = False
        which = np.flatnonzero(fast)
        if which.size:
            bk.observe(
                self._sessions, self._control, which, self._obs, self._info, self._ticks, T_SCALE
            )
            rewards[which] = self._info[which, _INFO_COL["reward"]]
            _add_rows(infos, self._info, which, self._names, n)
        for i, (obs, reward, term, trunc, info) in results.items():
            self._obs[i] = obs
            rewards[i] = reward
            terminated[i] = term
            truncated[i] = trunc
            _add_info(infos, info, i, n)
        self._elapsed[stepping] += 1
        truncated |= stepping & ~terminated & (self._elapsed * self._ticks >= self._max_ticks)
        if self.max_episode_steps is not None:
            truncated |= stepping & (self._elapsed >= self.max_episode_steps)
        done = terminated | truncated
        if self.autoreset_mode == AutoresetMode.SAME_STEP and done.any():
            final_obs = np.full(n, None, dtype=object)
            final_info: dict[str, Any] = {}
            for i in np.flatnonzero(done).tolist():
                final_obs[i] = self._obs[i].copy()
                _add_info(final_info, _session_info(infos, i), i, n)
                obs, info = self._reset_session(i, None, None)
                self._obs[i] = obs
                _set_info(infos, info, i, n)
            infos["final_obs"], infos["_final_obs"] = final_obs, done.copy()
            infos["final_info"], infos["_final_info"] = final_info, done.copy()
        for i in np.flatnonzero(resetting).tolist():  # NEXT_STEP: the sessions that ended
            obs, info = self._reset_session(i, None, None)
            self._obs[i] = obs
            _set_info(infos, info, i, n)
        self._autoreset = (
            done if self.autoreset_mode != AutoresetMode.SAME_STEP else np.zeros(n, bool)
        )
        return self._obs.copy(), rewards, terminated, truncated, infos

    def close_extras(self, **kwargs: Any) -> None:
        """Close every session and the thread pool."""
        if self._pool is not None:
            self._pool.shutdown()
            self._pool = None
        for env in self.envs:
            env.close()

    def sync(self) -> None:
        """Bring every session's Python objects up to date with its compiled state (they lag
        behind between the steps that needed no Python), e.g. before reading
        ``envs[i].motion``."""
        for i, env in enumerate(self.envs):
            steps = env.compiled_steps
            if self._compiled[i] and steps is not None and not env.terminated:
                steps.store()

    # ------------------------------------------------------------------ internals
    def _step_compiled(
        self,
        act: np.ndarray,
        compiled: np.ndarray,
        results: dict[int, tuple[np.ndarray, float, bool, bool, dict[str, Any]]],
    ) -> None:
        """One step of the sessions ``compiled`` in rounds: all of them in compiled code, then
        each one that stopped for Python gets its tick there, and so on until every step is
        done."""
        ctl = self._control
        ctl[:, _C.active] = compiled
        target = self.envs[0].choice_mode == "target"
        pause = np.ones(self.num_envs)
        if target:
            col = act[:, 2].tolist()
            for i in np.flatnonzero(compiled).tolist():
                pause[i] = duration_factor(col[i])  # as LangCtrlEnv.take_choice
        bk.begin(self._sessions, ctl, act, pause, self._ticks, COMMAND_MIN)
        while True:
            self._run_round()
            done = ctl[:, _C.left] <= 0.0
            need = (ctl[:, _C.active] != 0.0) & (ctl[:, _C.answer] != ek.R_DONE)
            ctl[done & ~need, _C.active] = 0.0
            if not need.any():
                return
            for i in np.flatnonzero(need).tolist():
                self._python_event(i, act[i], results)

    def _run_round(self) -> None:
        ctl, sessions = self._control, self._sessions
        if self.parallel == "prange" and self.threads > 1:
            numba.set_num_threads(self.threads)
            bk.run_parallel(sessions, ctl)
        elif self._pool is not None:
            active = np.flatnonzero(ctl[:, _C.active] != 0.0)
            if active.size <= CHUNK:  # nothing to share
                bk.run_serial(sessions, ctl, active)
                return
            chunks = [active[k : k + CHUNK] for k in range(0, active.size, CHUNK)]
            taken = iter(range(len(chunks)))  # next() under the GIL: each chunk taken once

            def drain() -> None:
                for k in taken:
                    bk.run_serial(sessions, ctl, chunks[k])  # without the GIL

            futures = [self._pool.submit(drain) for _ in range(self.threads - 1)]
            drain()  # this thread takes chunks too: whichever thread is running takes the next
            for f in futures:
                f.result()
        else:
            bk.run_serial(sessions, ctl, np.arange(self.num_envs))

    def _python_event(
        self,
        i: int,
        action: np.ndarray,
        results: dict[int, tuple[np.ndarray, float, bool, bool, dict[str, Any]]],
    ) -> None:
        """Session ``i``'s compiled ticks stopped for Python: its state into its Python objects,
        the tick (or the rest of it) there, then back into the compiled round, or the step
        finished in Python where the episode ended or the ticks can no longer be compiled."""
        env, ctl = self.envs[i], self._control[i]
        steps = env.compiled_steps
        assert steps is not None
        env.take_choice(action[2:].tolist())
        em_int, pace_int = steps.store()
        p_cmd, a_cmd = float(ctl[_C.p_cmd]), float(ctl[_C.a_cmd])
        em, pace, used = env.finish_event(int(ctl[_C.answer]), int(ctl[_C.code]), p_cmd, a_cmd)
        em_int += em * env.dt
        pace_int += pace * env.dt
        left = int(ctl[_C.left]) - used
        if env.terminated or not steps.usable():
            em_int, pace_int = env.run_ticks(p_cmd, a_cmd, left, em_int, pace_int)
            results[i] = env.step_result(em_int, pace_int)
            ctl[_C.active] = 0.0
            self._compiled[i] = False  # until its next reset
            return
        steps.load(em_int, pace_int)
        t_speech = env.t_speech
        ctl[_C.t_speech] = math.nan if t_speech is None else t_speech
        ctl[_C.left] = left
        ctl[_C.answer] = ek.R_DONE
        ctl[_C.active] = 1.0 if left > 0 else 0.0

    def _reset_session(
        self, i: int, seed: int | None, options: dict[str, Any] | None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        obs, info = self.envs[i].reset(seed=seed, options=options)
        self._bind(i)
        self._elapsed[i] = 0
        return obs, info

    def _bind(self, i: int) -> None:
        """Session ``i``'s arrays into the batch's tables (after its construction and every
        reset: its force table and cooperation history are new each episode)."""
        env = self.envs[i]
        steps = env.compiled_steps
        self._compiled[i] = steps is not None and steps.usable()
        if steps is None or not self._compiled[i]:
            return
        steps.load(0.0, 0.0)
        arrays = steps.arrays()
        graph = env.speech.graph
        order = steps.order
        tails = env.observation_tails(order)
        dur = np.array([graph.duration[u] for u in order], dtype=np.float64)
        named = dict(
            zip(
                (
                    "ws",
                    "path",
                    "aw",
                    "ai",
                    "jac",
                    "xpos",
                    "xmat",
                    "qpos",
                    "qvel",
                    "ctrl",
                    "qfrc",
                    "prm",
                    "tab",
                    "ptr",
                    "es",
                    "hist",
                    "table",
                    "mid",
                    "slot",
                    "kid_ptr",
                    "kids",
                    "lg",
                ),
                arrays,
                strict=True,
            )
        )
        named["tails"], named["dur"] = tails, dur
        ints = ("ai", "ptr", "kid_ptr", "kids")
        row = {}
        for name, arr in named.items():
            dtype = np.int64 if name in ints else (np.float32 if name == "tails" else np.float64)
            arr = np.asarray(arr)
            row[f"{name}_at"] = address(arr, dtype) if arr.size else 0
            row[f"{name}_n"] = arr.size
        values = np.zeros(bk.SESSION.size)
        bk.SESSION.pack(values, row)
        self._sessions[i] = values.astype(np.int64)
        self._keep[i] = tuple(named.values())  # alive while the batch reads them
        self._names[i] = order
        lim = env.paces.limits
        t_speech = env.t_speech
        bk.CONTROL.pack(
            self._control[i],
            {
                "active": False, "p_cmd": 1.0, "a_cmd": 1.0, "left": 0, "answer": 0, "code": 0,
                "length": env.motion.trajectory.length, "horizon": env.ticks_per_step * env.dt,
                "t_speech": math.nan if t_speech is None else t_speech, "w_em": env.w_em,
                "w_pace": env.w_pace, "p_max": lim.p_max, "a_max": lim.a_max,
            },
        )  # fmt: skip


def make_vector_env(num_envs: int = 1, **kwargs: Any) -> LangCtrlVectorEnv:
    """``vector_entry_point`` of ``LangCtrl-v0``: ``LangCtrlVectorEnv(num_envs, **kwargs)``."""
    return LangCtrlVectorEnv(num_envs, **kwargs)


# ---------------------------------------------------------------------------------- helpers
def _session_kwargs(
    n: int, env_kwargs: dict[str, Any], session_kwargs: Sequence[dict[str, Any]] | None
) -> list[dict[str, Any]]:
    """Each session's keyword arguments: the common ones, list items ``i mod len`` of
    ``exercise``/``phrase_graph``/``users``/``session``, then ``session_kwargs[i]``."""
    if session_kwargs is not None and len(session_kwargs) != n:
        raise ConfigError(f"session_kwargs: {n} mappings expected, got {len(session_kwargs)}")
    out = []
    for i in range(n):
        kw = dict(env_kwargs)
        for key in _PER_SESSION:
            value = kw.get(key)
            if isinstance(value, list | tuple):
                if not value:
                    raise ConfigError(f"{key}: an empty list")
                kw[key] = value[i % len(value)]
        if session_kwargs is not None:
            kw.update(session_kwargs[i])
        out.append(kw)
    return out


def _max_children(kwargs: dict[str, Any]) -> int:
    """The largest out-degree of the graph a session with ``kwargs`` speaks."""
    from langenv.exercise import resolve_exercise

    graph = kwargs.get("phrase_graph")
    if graph is None:
        if kwargs.get("trajectory") is not None:
            graph = resolve_exercise(None).graph
        else:
            graph = resolve_exercise(kwargs.get("exercise")).graph
    return _graph_children(str(graph_path(graph)))


def _graph_children(path: str) -> int:
    """A graph file's largest out-degree (the graph the sessions share: :func:`shared_graph`)."""
    return max(1, shared_graph(path).max_children)


def _checked_actions(actions: Any, shape: tuple[int, ...]) -> np.ndarray:
    """``actions`` as float64 of ``shape``, each in [-1, 1] (the single env's tolerance), or
    :class:`ActionError` naming the first bad session."""
    try:
        act = np.asarray(actions, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise ActionError(
            f"actions must be an array of shape {shape} of numbers, got {actions!r:.80} ({exc})"
        ) from None
    if act.shape != shape:
        raise ActionError(f"actions must have shape {shape}, got shape {act.shape}")
    ok = (act >= -1.000001) & (act <= 1.000001)  # also rejects NaN
    if not ok.all():
        i = int(np.flatnonzero(~ok.reshape(shape[0], -1).all(axis=1))[0])
        raise ActionError(
            f"session {i}: action must be finite and lie in [-1, 1], got {act[i].tolist()}"
        )
    return act


def _add_info(infos: dict[str, Any], info: dict[str, Any], i: int, n: int) -> None:
    """Session ``i``'s ``info`` into the batch's arrays (numbers float64, None as NaN; flags
    bool; strings and None-or-strings object), with their ``_key`` masks."""
    for key, value in info.items():
        arr = infos.get(key)
        if arr is None:
            arr = _empty(key, value, n)
            infos[key] = arr
            infos[f"_{key}"] = np.zeros(n, bool)
        if arr.dtype == np.float64:
            arr[i] = math.nan if value is None else value
            infos[f"_{key}"][i] = value is not None
        else:
            arr[i] = value
            infos[f"_{key}"][i] = True


def _set_info(infos: dict[str, Any], info: dict[str, Any], i: int, n: int) -> None:
    """:func:`_add_info`, replacing what session ``i`` had (a reset's info after the step's:
    the keys it lacks are masked off for ``i``)."""
    for key in list(infos):
        if key.startswith("_") and key not in ("_final_obs", "_final_info"):
            infos[key][i] = False
    _add_info(infos, info, i, n)


def _empty(key: str, value: Any, n: int) -> np.ndarray:
    if key in _FLAGS or isinstance(value, bool | np.bool_):
        return np.zeros(n, bool)
    if key in ("phrase", "safety_stop", "safety_message"):
        return np.full(n, None, dtype=object)
    return np.full(n, math.nan)


_FLOAT_KEYS = (
    "time", "t_x", "t_a", "em", "p", "a", "cooperation", "hand_speed", "progress",
    "path_deviation", "max_hand_speed", "reward_em", "reward_pace", "leg",
)  # fmt: skip


def _add_rows(
    infos: dict[str, Any], rows: np.ndarray, which: np.ndarray, names: list[tuple[str, ...]], n: int
) -> None:
    """The compiled info rows into the batch's arrays, for every session (those that stepped in
    Python or were reset then replace theirs): one column each."""
    cols = _INFO_COL
    every = np.ones(n, bool)
    for key in _FLOAT_KEYS:
        infos[key], infos[f"_{key}"] = rows[:, cols[key]].copy(), every.copy()
    for key in ("t_motion", "t_speech"):
        values = rows[:, cols[key]].copy()
        infos[key], infos[f"_{key}"] = values, ~np.isnan(values)
    for key in _FLAGS:
        infos[key], infos[f"_{key}"] = rows[:, cols[key]] != 0.0, every.copy()
    infos["am"], infos["_am"] = np.full(n, math.nan), np.zeros(n, bool)
    infos["reward_am"], infos["_reward_am"] = np.zeros(n), every.copy()
    phrase = np.full(n, None, dtype=object)
    index = rows[:, cols["phrase"]].astype(np.int64).tolist()
    for i in which.tolist():
        u = index[i]
        phrase[i] = names[i][u] if u >= 0 else None
    infos["phrase"], infos["_phrase"] = phrase, every.copy()
    infos["safety_stop"], infos["_safety_stop"] = np.full(n, None, dtype=object), every.copy()
    message = np.empty(n, dtype=object)
    message[:] = ""
    infos["safety_message"], infos["_safety_message"] = message, every.copy()


def _session_info(infos: dict[str, Any], i: int) -> dict[str, Any]:
    """Session ``i``'s entries of the batch's info arrays, as the single env's ``info`` (NaN
    back to None where its mask is False)."""
    out: dict[str, Any] = {}
    for key, arr in infos.items():
        if key.startswith("_") or key in ("final_obs", "final_info"):
            continue
        mask = infos.get(f"_{key}")
        if isinstance(arr, np.ndarray) and arr.dtype == np.float64:
            out[key] = float(arr[i]) if mask is None or mask[i] else None
        elif isinstance(arr, np.ndarray) and arr.dtype == np.bool_:
            out[key] = bool(arr[i])
        else:
            out[key] = arr[i]
    return out
