"""Behaviour pinned: whole seeded episodes hash to recorded digests.

Each case runs one episode and hashes everything an agent and an evaluation see at every step:
the observation (bytes), the reward, the end flags and every ``info`` value. A refactoring that
must not change behaviour (the observation layout, the policies' reading of it, the residual
map's features) keeps these digests; a change of behaviour must update them on purpose, with the
reason in its commit message.

Regenerate after an intended change with::

    PYTHONPATH=. python -m tests.test_pinned_episodes
"""

from __future__ import annotations

import hashlib
import math
from collections.abc import Callable
from typing import Any

import gymnasium as gym
import numpy as np
import pytest

import langenv
from policies import load_policy
from train.wrappers import ResidualLCWrapper

#: digest of each case (see :func:`run_case`)
PINNED: dict[str, str] = {
    "lc-500hz-seed3": "f91984cde4996f71ac663de81fdba961553f03c80e57cb2877a21f2db5b360a8",
    "lc-end-25hz-seed5": "4fe00693fef4d2a1cabc1aba2d53b9a8e56e5a95dc3b2f1381eceb0898e71c04",
    "ac-25hz-seed1": "cb9b220c590c202545c036d498d1ff679745f4051eaefa58253c7a9308e97b77",
    "random-scores-50hz-seed2": "dad15ece8555f807a9c89dc84c41434a813c6a4ef8adb14a928f7a669c5d6c0b",
    "residual-25hz-seed4": "a95b625e99323de6a6d8feec595c65d1e8fedfe2489c9a740057c842e0d96e70",
}


def _value_bytes(value: Any) -> bytes:
    if isinstance(value, np.ndarray):
        return value.dtype.str.encode() + value.tobytes()
    if isinstance(value, bool | np.bool_) or value is None or isinstance(value, str):
        return repr(value).encode()
    if isinstance(value, int | float | np.integer | np.floating):
        return float(value).hex().encode()
    raise TypeError(f"cannot hash {type(value).__name__}")


def _hash_step(h: Any, obs: np.ndarray, reward: float, term: bool, trunc: bool, info: dict) -> None:
    h.update(_value_bytes(np.asarray(obs)))
    for v in (reward, term, trunc):
        h.update(_value_bytes(v))
    for key in sorted(info):
        h.update(key.encode() + b"=" + _value_bytes(info[key]) + b";")


def _episode(
    env: gym.Env, act: Callable[[np.ndarray, int], np.ndarray], seed: int
) -> tuple[str, int]:
    """Run one episode; returns (sha256 of every step, number of steps)."""
    h = hashlib.sha256()
    obs, info = env.reset(seed=seed)
    _hash_step(h, obs, 0.0, False, False, info)
    for k in range(100_000):
        obs, reward, term, trunc, info = env.step(act(obs, k))
        _hash_step(h, obs, reward, term, trunc, info)
        if term or trunc:
            return h.hexdigest(), k + 1
    raise AssertionError("episode did not end")


def _analytic(name: str, hz: int, seed: int) -> tuple[str, int]:
    policy = load_policy(name)
    policy.decision_hz = hz
    env = gym.make(
        langenv.ENV_ID,
        phrase_graph=policy.phrase_graph,
        decision_hz=hz,
        max_episode_steps=60 * hz,
    )
    policy.reset()
    return _episode(env, lambda obs, _k: policy.act(obs), seed)


def _random_scores(seed: int) -> tuple[str, int]:
    env = gym.make(langenv.ENV_ID, decision_hz=50, choice_mode="scores", max_episode_steps=3000)
    env.action_space.seed(seed)
    return _episode(env, lambda _obs, _k: env.action_space.sample(), seed)


def _residual(seed: int) -> tuple[str, int]:
    """The residual map (features included) under a fixed, varying correction."""
    env = ResidualLCWrapper(
        gym.make(langenv.ENV_ID, decision_hz=25, max_episode_steps=1500),
        pace_scale=0.3,
        audio_scale=0.1,
        choice_scale=0.5,
        terminal=1.0,
        k_em=1.0,
    )

    def act(_obs: np.ndarray, k: int) -> np.ndarray:
        return np.array([math.sin(0.1 * k), math.cos(0.07 * k), math.sin(0.05 * k)], np.float32)

    return _episode(env, act, seed)


CASES: dict[str, Callable[[], tuple[str, int]]] = {
    "lc-500hz-seed3": lambda: _analytic("lc", 500, 3),
    "lc-end-25hz-seed5": lambda: _analytic("lc-end", 25, 5),
    "ac-25hz-seed1": lambda: _analytic("ac", 25, 1),
    "random-scores-50hz-seed2": lambda: _random_scores(2),
    "residual-25hz-seed4": lambda: _residual(4),
}


@pytest.mark.parametrize("case", sorted(CASES))
def test_episode_matches_its_pinned_digest(case: str) -> None:
    digest, steps = CASES[case]()
    assert steps > 10
    assert digest == PINNED[case], f"{case}: {steps} steps, digest {digest}"


if __name__ == "__main__":
    for name, run in CASES.items():
        d, n = run()
        print(f'    "{name}": "{d}",  # {n} steps')
