"""Behaviour pinned: whole seeded episodes against a recorded reference, on any CPU.

Each case runs one episode and records what an agent and an evaluation see at every step: the
observation, the reward, the end flags and every ``info`` value. The reference
(``tests/data/pinned_episodes.json``) keeps, per case:

* **exactly**: the number of steps and a SHA-256 of the discrete part of every step (the end
  flags, the phrase spoken, ``in_pause``/``motion_done``/``speech_done``, the safety stop and
  its message, which values are ``None``), and the phrases in order;
* **to a stated tolerance**: every float (observation entries, reward, reward terms, info
  values) at every one of the first 20 steps and at 30 steps spread over the rest, the last
  included: ``|x - x_ref| <= ATOL + RTOL |x_ref|``.

Why a tolerance and not a digest of the floats: the episodes are bit-identical on one machine
and across every x86-64-v3 dispatch setting we can switch (NumPy's AVX-512 loops off, OpenBLAS's
Haswell / Prescott / SkylakeX kernels, Numba's ``generic`` target: measured identical, see
``docs/ARCHITECTURE.md``, "Same results on every machine"), but a CPU we could not try may still
round one operation of a third-party library differently; such a difference starts at 1e-16 and
has been seen to grow to at most 2e-9 (relative) over a whole episode. RTOL = ATOL = 1e-6 (s, m,
N, m/s, pace units) leaves a margin of 500 over that, while a real change of behaviour moves these
values by far more: ``test_a_one_percent_gain_change_fails`` changes one gain by 1 % and
requires the comparison to fail.

Regenerate after an intended change of behaviour (and say why in the commit message)::

    PYTHONPATH=. python -m tests.test_pinned_episodes
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import math
from collections.abc import Callable
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import pytest

import langenv
from langenv.control.admittance import AdmittanceParams
from langenv.control.pacing import AlignerGains
from langenv.exercise import speak
from policies import load_policy
from train.wrappers import ResidualLCWrapper

pytestmark = pytest.mark.portable

REFERENCE = Path(__file__).parent / "data" / "pinned_episodes.json"
RTOL = 1e-6
"""Relative tolerance of every recorded float (see the module docstring)."""
ATOL = 1e-6
"""Absolute tolerance of every recorded float, in its own unit (s, m, N, m/s, pace)."""
HEAD = 20
"""Every step of the episode's start is kept (a change shows there first)."""
SPREAD = 30
"""Steps kept over the rest of the episode, evenly spread, the last included."""

Act = Callable[[np.ndarray, int], np.ndarray]


@dataclasses.dataclass
class Episode:
    """One episode's record: per step, its floats (name -> value) and its discrete values."""

    floats: list[dict[str, float]]
    discrete: list[tuple[Any, ...]]
    phrases: list[str]

    @property
    def steps(self) -> int:
        return len(self.floats) - 1  # the reset's record comes first

    def digest(self) -> str:
        return hashlib.sha256(repr(self.discrete).encode()).hexdigest()

    def kept(self) -> list[int]:
        """The indices of the records compared by value."""
        n = len(self.floats)
        rest = np.linspace(HEAD, n - 1, SPREAD).round().astype(int).tolist() if n > HEAD else []
        return sorted(set(range(min(HEAD, n))) | set(rest))

    def to_json(self) -> dict[str, Any]:
        kept = self.kept()
        keys = sorted(set().union(*(self.floats[i] for i in kept)))
        return {
            "steps": self.steps,
            "discrete_sha256": self.digest(),
            "phrases": self.phrases,
            "keys": keys,
            "floats": {str(i): [self.floats[i].get(k) for k in keys] for i in kept},
        }


def _record(obs: Any, reward: float, term: bool, trunc: bool, info: dict) -> tuple[dict, tuple]:
    floats = {f"obs[{i}]": float(v) for i, v in enumerate(np.asarray(obs).ravel().tolist())}
    floats["reward"] = float(reward)
    discrete: list[Any] = [bool(term), bool(trunc)]
    for key in sorted(info):
        value = info[key]
        if isinstance(value, bool | np.bool_) or value is None or isinstance(value, str):
            kept = value if value is None or isinstance(value, str) else bool(value)
            discrete.append((key, kept))
        elif isinstance(value, int | float | np.integer | np.floating):
            floats[key] = float(value)
        else:
            raise TypeError(f"cannot record info[{key!r}] of type {type(value).__name__}")
    return floats, tuple(discrete)


def _episode(env: gym.Env, act: Act, seed: int) -> Episode:
    ep = Episode([], [], [])

    def keep(obs: Any, reward: float, term: bool, trunc: bool, info: dict) -> None:
        floats, discrete = _record(obs, reward, term, trunc, info)
        ep.floats.append(floats)
        ep.discrete.append(discrete)
        phrase = info.get("phrase")
        if isinstance(phrase, str) and (not ep.phrases or ep.phrases[-1] != phrase):
            ep.phrases.append(phrase)

    obs, info = env.reset(seed=seed)
    keep(obs, 0.0, False, False, info)
    for k in range(100_000):
        obs, reward, term, trunc, info = env.step(act(obs, k))
        keep(obs, reward, term, trunc, info)
        if term or trunc:
            return ep
    raise AssertionError("episode did not end")


def _analytic(
    name: str,
    hz: int,
    seed: int,
    admittance: AdmittanceParams | None = None,
    gains: AlignerGains | None = None,
    graph: str | None = None,
) -> Episode:
    policy = load_policy(name)
    if gains is not None:
        policy = dataclasses.replace(policy, gains=gains)  # type: ignore[type-var]
    policy.decision_hz = hz
    env = gym.make(
        langenv.ENV_ID,
        phrase_graph=graph or speak(policy).ref,
        decision_hz=hz,
        max_episode_steps=60 * hz,
        admittance=admittance,
    )
    policy.reset()
    return _episode(env, lambda obs, _k: policy.act(obs), seed)


def _random_scores(seed: int, graph: str = "default") -> Episode:
    env = gym.make(
        langenv.ENV_ID,
        phrase_graph=graph,
        decision_hz=50,
        choice_mode="scores",
        max_episode_steps=3000,
    )
    env.action_space.seed(seed)
    return _episode(env, lambda _obs, _k: env.action_space.sample(), seed)


def _residual(seed: int) -> Episode:
    """The residual map (features included) under a fixed, varying correction."""
    env = ResidualLCWrapper(
        gym.make(langenv.ENV_ID, phrase_graph="study", decision_hz=25, max_episode_steps=1500),
        pace_scale=0.3,
        audio_scale=0.1,
        choice_scale=0.5,
        terminal=1.0,
        k_em=1.0,
    )

    def act(_obs: np.ndarray, k: int) -> np.ndarray:
        return np.array([math.sin(0.1 * k), math.cos(0.07 * k), math.sin(0.05 * k)], np.float32)

    return _episode(env, act, seed)


CASES: dict[str, Callable[[], Episode]] = {
    # the study's phrase graphs
    "lc-500hz-seed3": lambda: _analytic("lc", 500, 3, graph="study"),
    "lc-end-25hz-seed5": lambda: _analytic("lc-end", 25, 5, graph="study"),
    "ac-25hz-seed1": lambda: _analytic("ac", 25, 1),
    "random-scores-50hz-seed2": lambda: _random_scores(2, graph="study"),
    "residual-25hz-seed4": lambda: _residual(4),
    # the default graph (pauses whose length the env plans, shorter late wordings)
    "lc-default-graph-25hz-seed6": lambda: _analytic("lc", 25, 6),
    "random-scores-default-graph-50hz-seed2": lambda: _random_scores(2),
}


def mismatches(episode: Episode, reference: dict[str, Any]) -> list[str]:
    """What differs between ``episode`` and its ``reference`` record (empty: the same)."""
    found = []
    if episode.steps != reference["steps"]:
        found.append(f"{episode.steps} steps, recorded {reference['steps']}")
    if episode.phrases != reference["phrases"]:
        found.append(f"phrases {episode.phrases}, recorded {reference['phrases']}")
    if episode.digest() != reference["discrete_sha256"]:
        found.append("the discrete values (end flags, phrase, pause, stop) differ at some step")
    keys = reference["keys"]
    for index, values in reference["floats"].items():
        i = int(index)
        if i >= len(episode.floats):
            break
        got = episode.floats[i]
        recorded = {k: v for k, v in zip(keys, values, strict=True) if v is not None}
        if set(got) != set(recorded):
            found.append(f"step {i}: values {sorted(got)}, recorded {sorted(recorded)}")
            continue
        for key, ref in recorded.items():
            x = got[key]
            same = (math.isnan(x) and math.isnan(ref)) or abs(x - ref) <= ATOL + RTOL * abs(ref)
            if not same:
                found.append(f"step {i}: {key} = {x!r}, recorded {ref!r}")
    return found


def _reference() -> dict[str, Any]:
    return json.loads(REFERENCE.read_text())


@pytest.mark.parametrize("case", sorted(CASES))
def test_episode_matches_its_recorded_reference(case: str) -> None:
    episode = CASES[case]()
    assert episode.steps > 10
    found = mismatches(episode, _reference()[case])
    assert not found, f"{case}: " + "; ".join(found[:10])


@pytest.mark.parametrize(
    ("case", "changed"),
    [
        ("ac-25hz-seed1", lambda: _analytic("ac", 25, 1, AdmittanceParams(damping=80.8))),
        (
            "lc-end-25hz-seed5",
            lambda: _analytic("lc-end", 25, 5, None, AlignerGains(k_c=10.1), "study"),
        ),
    ],
    ids=["admittance-damping+1%", "lc-k_c+1%"],
)
def test_a_one_percent_gain_change_fails(case: str, changed: Callable[[], Episode]) -> None:
    """The tolerance is not so wide that a real change passes: one gain 1 % off must show."""
    assert AdmittanceParams().damping == 80.0 and AlignerGains().k_c == 10.0  # what +1 % means
    assert mismatches(changed(), _reference()[case])


def test_the_comparison_reads_floats_with_the_stated_tolerance() -> None:
    ep = Episode([{"x": 1.0}], [()], [])
    ref = {"steps": 0, "phrases": [], "discrete_sha256": ep.digest(), "keys": ["x"]}
    ref["floats"] = {"0": [1.0]}
    assert not mismatches(ep, ref)
    ep.floats[0]["x"] = 1.0 + 0.9 * (ATOL + RTOL)
    assert not mismatches(ep, ref)
    ep.floats[0]["x"] = 1.0 + 1.1 * (ATOL + RTOL)
    assert mismatches(ep, ref)


if __name__ == "__main__":
    record = {}
    for name, run in CASES.items():
        episode = run()
        record[name] = episode.to_json()
        print(f"{name}: {episode.steps} steps, phrases {episode.phrases}")
    REFERENCE.write_text(json.dumps(record, sort_keys=True).replace("], ", "],\n") + "\n")
    print(f"wrote {REFERENCE}")
