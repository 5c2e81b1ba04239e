"""The envs a training run steps: which vector env, and the factories of its envs.

rl-zoo3's ``ExperimentManager.create_envs`` in one module: the training VecEnv (one batched env,
:mod:`train.vec_env`, where it applies; else one env per process or all in this process, see
:func:`use_batched` and :func:`use_subprocesses`), normalised as the config says, and the
periodic evaluation's VecEnv (the same held-out users every time, normalisation in eval mode).
Training env ``i`` is seeded ``seed + i`` whichever vector env steps it, so every choice gives
the same run. Subprocess workers leave Ctrl-C to the learner (:class:`_SubprocVecEnv`).
"""

from __future__ import annotations

import signal
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np
from stable_baselines3.common.vec_env import SubprocVecEnv, VecNormalize

from langenv.errors import ConfigError
from langenv.kernels.cores import usable_cores
from train.config import Run, WrapperChain

__all__ = [
    "close_env",
    "env_has_attr",
    "exercise_kwargs",
    "make_envs",
    "residual_section",
    "use_batched",
    "use_subprocesses",
]


def use_batched(vec_env: str, run: Run) -> bool:
    """Whether ``vec_env`` (see :class:`~train.config.TrainArgs`) steps ``run``'s envs as one
    batched env.

    Raises:
        ConfigError: ``"batched"`` for a run it cannot step (worlds, another wrapper).
    """
    from train.vec_env import BATCHED_WRAPPERS

    if vec_env not in ("batched", "auto"):
        return False
    names = [_dotted(k) for k, _ in (run.wrapper.chain if run.wrapper is not None else [])]
    why = ""
    if run.args.env_id != "LangCtrl-v0":
        why = f"env {run.args.env_id!r} (batched: LangCtrl-v0)"
    elif run.worlds is not None:
        why = "a run across worlds (its envs change scripts per episode)"
    elif any(name not in BATCHED_WRAPPERS for name in names):
        why = f"env_wrapper {names} (batched: {', '.join(BATCHED_WRAPPERS)})"
    if why and vec_env == "batched":
        raise ConfigError(f"--vec-env batched cannot step {why}; use subproc or dummy")
    return not why


def _dotted(klass: Any) -> str:
    return f"{klass.__module__}.{klass.__qualname__}"


def use_subprocesses(vec_env: str, n_envs: int) -> bool:
    """Whether ``vec_env`` (see :class:`~train.config.TrainArgs`) runs ``n_envs`` envs in
    subprocesses (with more usable CPU cores than envs, for ``"auto"``)."""
    if n_envs < 2 or vec_env == "dummy":
        return False
    return vec_env == "subproc" or usable_cores() > n_envs


def make_envs(run: Run) -> tuple[Any, Any]:
    """Training VecEnv (normalised) and evaluation VecEnv (normalisation in eval mode; None
    without periodic evaluation).

    Raises:
        ConfigError: for an exercise that fails its checks, or a vector env that cannot step
            the run's envs.
    """
    from stable_baselines3.common.vec_env import DummyVecEnv

    import langenv  # noqa: F401  (registers the env)

    a = run.args
    cls = _SubprocVecEnv if use_subprocesses(a.vec_env, run.n_envs) else DummyVecEnv
    if run.worlds is not None and not use_batched(a.vec_env, run):
        return _make_world_envs(run, cls)
    per_env = exercise_kwargs(run.env_kwargs)
    env = _training_env(run, per_env, cls)
    if run.normalize is not None:
        env = VecNormalize(env, **run.normalize)
    eval_env: Any = None
    if a.n_eval_episodes > 0:
        eval_env = _eval_env(run, per_env)
    return env, eval_env


def _training_env(run: Run, per_env: list[dict[str, Any]], cls: Any) -> Any:
    """The training VecEnv (not normalised) of ``run``'s envs, env ``i`` guiding exercise
    ``i mod k`` of the ``k`` in ``per_env``: one batched env, or ``cls`` (a DummyVecEnv or a
    :class:`_SubprocVecEnv`) of one env each."""
    from stable_baselines3.common.env_util import make_vec_env

    a = run.args
    env: Any
    if use_batched(a.vec_env, run):
        from train.vec_env import make_batched_vec_env

        chain = run.wrapper.chain if run.wrapper is not None else []
        sessions = [
            {k: v for k, v in per_env[i % len(per_env)].items() if k != "max_episode_steps"}
            for i in range(run.n_envs)
        ]
        env = make_batched_vec_env(
            run.n_envs,
            {"max_episode_steps": run.env_kwargs.get("max_episode_steps")},
            a.seed,
            [(_dotted(k), kw) for k, kw in chain],
            session_kwargs=sessions,
        )
    elif len(per_env) == 1 and not getattr(run.wrapper, "monitor_outside", False):
        env = make_vec_env(
            a.env_id,
            n_envs=run.n_envs,
            seed=a.seed,
            vec_env_cls=cls,
            env_kwargs=run.env_kwargs,
            wrapper_class=run.wrapper,
        )
    else:  # make_vec_env gives every env the same kwargs: its loop, exercise i mod k
        fns: list[Any] = [
            _EnvFn(run.wrapper, a.seed, i, env_id=a.env_id, kwargs=per_env[i % len(per_env)])
            for i in range(run.n_envs)
        ]
        env = cls(fns)
        env.seed(a.seed)
    return env


def _eval_env(run: Run, per_env: list[dict[str, Any]]) -> Any:
    """The periodic evaluation's VecEnv: one env per exercise, the held-out users
    ``eval_seed ..`` spread over them, normalisation (if any) in eval mode."""
    import gymnasium as gym
    from stable_baselines3.common.vec_env import DummyVecEnv

    from train.wrappers import SeedCycle

    a = run.args
    seeds = [a.eval_seed + i for i in range(a.n_eval_episodes)]
    chain = run.wrapper.chain if run.wrapper is not None else []
    k = len(per_env)

    def make_eval_env(j: int) -> Any:
        wrap = WrapperChain(chain, ((SeedCycle, {"seeds": seeds[j::k] or seeds[:1]}),))
        return lambda: _monitored(gym.make(a.env_id, **per_env[j]), wrap)

    # Not make_vec_env: it seeds the first reset at random even with seed=None, which would
    # override SeedCycle and make the first evaluation episode a random user. A bare
    # DummyVecEnv passes seed=None, so SeedCycle picks eval_seed, eval_seed + 1, ...
    eval_env: Any = DummyVecEnv([make_eval_env(j) for j in range(k)])
    if run.normalize is not None:
        kw = {k: v for k, v in run.normalize.items() if k != "norm_reward"}
        eval_env = VecNormalize(eval_env, training=False, norm_reward=False, **kw)
    return eval_env


def _make_world_envs(run: Run, cls: Any) -> tuple[Any, Any]:
    """Training and validation VecEnvs across the worlds of ``run.worlds``
    (:mod:`langenv.worlds`): training env ``i`` draws its worlds from seed ``seed + i``; the
    periodic evaluation cycles through ``n_eval_episodes`` validation (exercise, user) pairs."""
    from stable_baselines3.common.vec_env import DummyVecEnv

    a, split = run.args, run.worlds
    split.check()
    fns: list[Any] = [
        _WorldFn(run.wrapper, a.seed, i, split=split, env_kwargs=run.env_kwargs)
        for i in range(run.n_envs)
    ]
    env = cls(fns)
    env.seed(a.seed)
    if run.normalize is not None:
        env = VecNormalize(env, **run.normalize)
    eval_env: Any = None
    if a.n_eval_episodes > 0:
        split.pairs("validation", a.n_eval_episodes)  # enough validation users, before training
        from langenv.worlds import WorldEnv

        n = a.n_eval_episodes
        eval_env = DummyVecEnv(
            [lambda: _monitored(WorldEnv(split, "validation", run.env_kwargs, n), run.wrapper)]
        )
        if run.normalize is not None:
            kw = {k: v for k, v in run.normalize.items() if k != "norm_reward"}
            eval_env = VecNormalize(eval_env, training=False, norm_reward=False, **kw)
    return env, eval_env


@dataclass(frozen=True)
class _Finished:
    """What a training env factory (picklable for subprocesses) does last, as ``make_vec_env``
    finishes each of its envs: the action space seeded ``seed + rank``, a Monitor, then
    ``wrapper`` (:func:`_monitored`)."""

    wrapper: Any
    seed: int | None
    rank: int

    def finish(self, env: Any) -> Any:
        if self.seed is not None:
            env.action_space.seed(self.seed + self.rank)
        return _monitored(env, self.wrapper)


@dataclass(frozen=True)
class _WorldFn(_Finished):
    """One training env across worlds: a :class:`~langenv.worlds.WorldEnv` with its
    TimeLimit's steps, finished (:class:`_Finished`)."""

    split: Any = None
    role: str = "train"
    env_kwargs: dict[str, Any] = field(default_factory=dict)

    def __call__(self) -> Any:
        from langenv.worlds import WorldEnv

        return self.finish(WorldEnv(self.split, self.role, self.env_kwargs))


def exercise_kwargs(env_kwargs: dict[str, Any]) -> list[dict[str, Any]]:
    """The env kwargs of each exercise of ``env_kwargs["exercise"]`` (one or a list), checked.

    Raises:
        ConfigError: an empty list, or an exercise that does not load or fails its checks.
    """
    from langenv.exercise import resolve_exercise
    from langenv.exercise.check import check_exercise
    from langenv.speech.graph import PhraseGraph, graph_path

    given = env_kwargs.get("exercise")
    if not isinstance(given, list | tuple):
        if given is not None:
            check_exercise(resolve_exercise(given))
        return [env_kwargs]
    if not given:
        raise ConfigError("env_kwargs.exercise: an empty list; give one exercise or several")
    widest = 1
    for ex in given:
        exercise = resolve_exercise(ex)
        check_exercise(exercise)
        graph = env_kwargs.get("phrase_graph") or exercise.graph
        widest = max(widest, PhraseGraph.load(graph_path(graph)).max_children)
    # one observation layout for all: the child blocks of the widest graph (unless given)
    common = {"max_children": widest, **env_kwargs}
    return [{**common, "exercise": ex} for ex in given]


@dataclass(frozen=True)
class _EnvFn(_Finished):
    """One training env of a list of exercises, made as ``make_vec_env`` makes each of its own
    and finished (:class:`_Finished`)."""

    env_id: str = ""
    kwargs: dict[str, Any] = field(default_factory=dict)

    def __call__(self) -> Any:
        import gymnasium as gym

        return self.finish(gym.make(self.env_id, **{"render_mode": "rgb_array", **self.kwargs}))


def residual_section(env: Any) -> dict[str, Any]:
    """The ResidualSpec of the training env's wrapper, if any (for ``PPOPolicy``)."""
    spec = env.get_attr("residual_spec")[0] if env_has_attr(env, "residual_spec") else None
    return asdict(spec) if spec is not None else {}


def env_has_attr(env: Any, name: str) -> bool:
    """Whether the first env of the VecEnv ``env`` (or its wrappers) has attribute ``name``."""
    try:
        env.get_attr(name, indices=[0])
    except AttributeError:
        return False
    return True


def _monitored(env: Any, wrapper: Any) -> Any:
    """``env`` with a Monitor and ``wrapper``, the Monitor inside it unless it must be outside
    (:attr:`WrapperChain.monitor_outside`), so that it counts the agent's steps."""
    from stable_baselines3.common.monitor import Monitor

    if wrapper is None:
        return Monitor(env)
    if getattr(wrapper, "monitor_outside", False):
        return Monitor(wrapper(env))
    return wrapper(Monitor(env))


class _IgnoreSigint:
    """Env factory for a worker process that leaves Ctrl-C to the learner process, which then
    closes the workers cleanly (instead of each worker dying with its own traceback)."""

    def __init__(self, make: Any) -> None:
        self.make = make

    def __call__(self) -> Any:
        signal.signal(signal.SIGINT, signal.SIG_IGN)
        return self.make()


class _SubprocVecEnv(SubprocVecEnv):
    """SubprocVecEnv whose workers ignore SIGINT (see :class:`_IgnoreSigint`) and whose rewards
    are float32, as a DummyVecEnv stores them (SB3's SubprocVecEnv passes Python floats on as
    float64), so that the two give the same run."""

    def __init__(self, env_fns: list[Any], start_method: str | None = None) -> None:
        from langenv.batch.warm import warm_up

        warm_up()  # compiled here once, before the workers start (they would compile together)
        super().__init__([_IgnoreSigint(fn) for fn in env_fns], start_method)

    def step_wait(self) -> Any:
        obs, rewards, dones, infos = super().step_wait()
        return obs, np.asarray(rewards, dtype=np.float32), dones, infos


def close_env(env: Any) -> None:
    """Close a VecEnv; a worker already gone is not an error worth a traceback."""
    try:
        env.close()
    except (EOFError, BrokenPipeError, ConnectionResetError):
        for proc in getattr(getattr(env, "venv", env), "processes", []):
            proc.terminate()
