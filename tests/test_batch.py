"""The batched env (langenv.batch) against the single env: the same sessions, bit for bit, and
Gymnasium's VectorEnv contract (spaces, seeding, the three autoreset modes, infos as arrays)."""

from __future__ import annotations

import math
from typing import Any

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.vector import AutoresetMode

import langenv
from langenv.batch import LangCtrlVectorEnv
from langenv.errors import ActionError, ConfigError

pytestmark = pytest.mark.xdist_group("batch")


def _actions(rng: np.random.Generator, n: int, dim: int = 3) -> np.ndarray:
    """Actions that move the paces and the choices (boundaries are chosen by them)."""
    return rng.uniform(-0.6, 0.6, (n, dim)).astype(np.float32)


def _same_info(batch: dict[str, Any], i: int, single: dict[str, Any]) -> None:
    for key, value in single.items():
        got, has = batch[key][i], batch[f"_{key}"][i]
        if value is None:
            assert not has or got is None, key
        elif isinstance(value, float):
            assert has and got == value, (key, got, value)
        else:
            assert has and got == value, (key, got, value)


def _compare(
    venv: LangCtrlVectorEnv, singles: list[gym.Env[Any, Any]], seed: int, steps: int
) -> int:
    """Step both with the same actions until every session's first episode ended (or
    ``steps``); returns the steps taken. SAME_STEP: the final step is in ``final_*``."""
    n = venv.num_envs
    rng = np.random.default_rng(seed)
    obs, _ = venv.reset(seed=seed)
    for i, env in enumerate(singles):
        ref, _ = env.reset(seed=seed + i)
        assert np.array_equal(obs[i], ref)
    live = [True] * n
    for t in range(steps):
        act = _actions(rng, n, venv.single_action_space.shape[0])  # type: ignore[index]
        obs, rew, term, trunc, info = venv.step(act)
        for i, env in enumerate(singles):
            if not live[i]:
                continue
            r_obs, r_rew, r_term, r_trunc, r_info = env.step(act[i])
            ended = bool(term[i] or trunc[i])
            got = info["final_obs"][i] if ended else obs[i]
            assert np.array_equal(got, r_obs), (t, i)
            assert rew[i] == r_rew and term[i] == r_term and trunc[i] == r_trunc, (t, i)
            _same_info(info["final_info"] if ended else info, i, r_info)
            live[i] = not ended
        if not any(live):
            return t + 1
    return steps


def test_sessions_equal_the_single_env_until_their_first_episode_ends() -> None:
    n = 4
    venv = LangCtrlVectorEnv(n, max_episode_steps=1500, autoreset_mode="SameStep")
    singles = [gym.make(langenv.ENV_ID) for _ in range(n)]
    taken = _compare(venv, singles, 123, 1500)
    assert taken < 1500  # every first episode ended
    venv.close()


def test_make_vec_builds_it_with_the_sessions_time_limit() -> None:
    venv = gym.make_vec(langenv.ENV_ID, num_envs=2, vectorization_mode="vector_entry_point")
    assert isinstance(venv.unwrapped, LangCtrlVectorEnv)
    assert venv.unwrapped.max_episode_steps is None  # no step count: each session's 60 s
    assert [e.max_seconds for e in venv.unwrapped.envs] == [60.0, 60.0]
    assert venv.metadata["autoreset_mode"] == AutoresetMode.NEXT_STEP
    single = gym.make(langenv.ENV_ID)
    assert venv.single_observation_space == single.observation_space
    assert venv.single_action_space == single.action_space
    assert venv.observation_space.shape == (2, *single.observation_space.shape)  # type: ignore[misc]
    obs, infos = venv.reset(seed=0)
    assert obs.shape == (2, *single.observation_space.shape) and obs.dtype == np.float32  # type: ignore[misc]
    assert venv.observation_space.contains(obs)
    assert infos["time"].dtype == np.float64 and infos["_time"].all()
    obs, rew, term, trunc, infos = venv.step(venv.action_space.sample())
    assert rew.dtype == np.float64 and term.dtype == np.bool_ and trunc.dtype == np.bool_
    assert infos["motion_done"].dtype == np.bool_ and infos["phrase"].dtype == object
    assert not infos["_am"].any() and np.isnan(infos["am"]).all()
    venv.close()


def test_next_step_autoreset_and_truncation() -> None:
    """A session that ended is reset at the next step: reward 0, its first observation, which
    is the single env's next episode (the session's own generator goes on)."""
    venv = LangCtrlVectorEnv(2, max_episode_steps=5)
    single = gym.make(langenv.ENV_ID, max_episode_steps=5)
    obs, _ = venv.reset(seed=7)
    single.reset(seed=7)
    zero = np.zeros((2, 3), np.float32)
    for _ in range(4):
        venv.step(zero)
        single.step(zero[0])
    obs, rew, term, trunc, info = venv.step(zero)
    _, r_rew, _, r_trunc, _ = single.step(zero[0])
    assert trunc.all() and not term.any() and rew[0] == r_rew and r_trunc
    obs, rew, term, trunc, info = venv.step(zero)
    first, _ = single.reset()
    assert np.array_equal(obs[0], first) and (rew == 0.0).all() and not (term | trunc).any()
    assert (info["time"] == 0.0).all() and not info.get("_reward_em", np.zeros(2, bool)).any()
    venv.close()


def test_disabled_autoreset_needs_a_reset_mask() -> None:
    venv = LangCtrlVectorEnv(2, max_episode_steps=2, autoreset_mode=AutoresetMode.DISABLED)
    venv.reset(seed=[3, 9])
    zero = np.zeros((2, 3), np.float32)
    venv.step(zero)
    _, _, _, trunc, _ = venv.step(zero)
    assert trunc.all()
    with pytest.raises(ConfigError, match="reset_mask"):
        venv.step(zero)
    single = gym.make(langenv.ENV_ID)
    obs, infos = venv.reset(seed=[None, 9], options={"reset_mask": np.array([False, True])})
    assert np.array_equal(obs[1], single.reset(seed=9)[0])
    assert infos["_time"].tolist() == [False, True]
    with pytest.raises(ConfigError, match="reset_mask"):
        venv.step(zero)  # session 0 still ended
    venv.close()


def test_per_session_exercises_and_a_python_user() -> None:
    """Sessions of other exercises share one layout; a callable user ticks in Python."""
    push = lambda t, v, b: -3.0 * np.asarray(b)  # noqa: E731
    exercises = ["external_rotation", "hand_to_mouth"]
    venv = LangCtrlVectorEnv(3, exercise=exercises, session_kwargs=[{}, {}, {"users": push}])
    widest = venv.envs[0].max_children
    singles = [
        gym.make(langenv.ENV_ID, exercise=exercises[i % 2], max_children=widest, **kw)
        for i, kw in enumerate([{}, {}, {"users": push}])
    ]
    assert [e.exercise.name for e in venv.envs] == [*exercises, exercises[0]]
    assert _compare(venv, singles, 5, 60) == 60
    venv.close()


def test_bad_actions_and_arguments_are_named() -> None:
    venv = LangCtrlVectorEnv(2)
    venv.reset(seed=0)
    bad = np.zeros((2, 3), np.float32)
    bad[1, 0] = math.nan
    with pytest.raises(ActionError, match="session 1"):
        venv.step(bad)
    with pytest.raises(ActionError, match="shape"):
        venv.step(np.zeros((3, 3)))
    for kwargs in ({"num_envs": 0}, {"autoreset_mode": "later"}, {"parallel": "gpu"}):
        with pytest.raises(ConfigError):
            LangCtrlVectorEnv(**{"num_envs": 1, **kwargs})
    venv.close()


@pytest.mark.parametrize("parallel", ["prange", "pool", "serial"])
def test_every_parallel_mode_gives_the_same_steps(parallel: str) -> None:
    ref = LangCtrlVectorEnv(3, parallel="serial")
    venv = LangCtrlVectorEnv(3, parallel=parallel, threads=2)  # type: ignore[arg-type]
    a, _ = ref.reset(seed=11)
    b, _ = venv.reset(seed=11)
    assert np.array_equal(a, b)
    rng = np.random.default_rng(1)
    for _ in range(40):
        act = _actions(rng, 3)
        out_a, out_b = ref.step(act), venv.step(act)
        for x, y in zip(out_a[:4], out_b[:4], strict=True):
            assert np.array_equal(x, y)
    ref.close()
    venv.close()


def test_a_protective_stop_and_the_end_in_the_batch() -> None:
    """A person strong enough to trip the force limit in one session, ordinary ones in the
    others: the stop (Python's part of a compiled tick) and the other sessions as alone."""
    from langenv.users import SyntheticUser
    from langenv.users.synthetic import LogNormal, SyntheticUserParams

    params = SyntheticUserParams.calibrated(
        count_pmf=(0.0, 1.0), p_start_resisting=1.0, max_excess=400.0,
        magnitude=LogNormal(300.0, 0.01), rise=LogNormal(0.5, 0.01),
    )  # fmt: skip
    kwargs = [{"users": SyntheticUser(params)}, {}, {}]
    venv = LangCtrlVectorEnv(3, autoreset_mode="SameStep", session_kwargs=kwargs)
    singles = [
        gym.make(langenv.ENV_ID, users=SyntheticUser(params)),
        gym.make(langenv.ENV_ID),
        gym.make(langenv.ENV_ID),
    ]
    _compare(venv, singles, 21, 1500)
    stop = singles[0].unwrapped.motion.safety_stop  # type: ignore[attr-defined]
    assert stop is not None and stop.limit == "force"
    venv.close()
