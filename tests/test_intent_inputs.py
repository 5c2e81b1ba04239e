"""The learned coach reads what each wording asks: ChoicePoints' ``child_intents`` (issue 46), the
same inputs in training and at run time, and nothing changed without it."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import pytest
import yaml

from langenv.errors import ConfigError, ModelError
from langenv.exercise.script import speak
from policies.learned import (
    FEATURES,
    INTENT_INPUTS,
    MlpActor,
    PPOPolicy,
    ResidualLC,
    ResidualSpec,
    observation_layout,
    widened_inputs,
)
from train.choices import ChoicePoints

ROOT = Path(__file__).resolve().parents[1]
N = len(INTENT_INPUTS)


def _env() -> Any:
    return gym.make("LangCtrl-v0", decision_hz=500, choice_mode="target")


def _choices(child_intents: bool, seed: int = 0) -> tuple[ChoicePoints, list[Any]]:
    """Every choice of a base episode (zero correction): ``(observation, the children's intents
    as the graph has them, reward)``."""
    env = ChoicePoints(_env(), child_intents=child_intents)
    obs, _ = env.reset(seed=seed)
    plant = env._plant()
    seen, done = [], False
    while not done:
        truth = [plant.graph.intent(c) or "none" for c in plant.speech.candidates]
        obs_next, reward, terminated, truncated, _ = env.step(np.zeros(3, np.float32))
        seen.append((obs, truth, reward))
        obs, done = obs_next, terminated or truncated
    return env, seen


def _decode(obs: np.ndarray, max_children: int) -> list[str]:
    part = obs[-max_children * N :].reshape(max_children, N)
    assert set(np.unique(part)) <= {0.0, 1.0} and (part.sum(axis=1) <= 1).all()
    return [INTENT_INPUTS[int(np.argmax(row))] for row in part if row.any()]


def test_intent_inputs_say_what_each_child_asks_on_the_default_graph() -> None:
    env, seen = _choices(True)
    k = env.residual_spec.max_children
    # the first leg's first choice: line 15's alternatives, line 16's, then the leg's gate
    first = _decode(seen[0][0], k)
    line_15, line_16 = ["relax", "faster", "guide", "guide"], ["encourage", "slower", "encourage"]
    assert first == [*line_15, *line_16, "none"]
    assert len(seen) > 3
    for obs, truth, _ in seen:
        assert _decode(obs, k) == truth
    assert env.observation_space.shape == (seen[0][0].size,)


def test_without_child_intents_the_observation_is_unchanged() -> None:
    on_env, on = _choices(True)
    off_env, off = _choices(False)
    n_env = int(np.prod(off_env.env.observation_space.shape))
    assert off_env.observation_space.shape == (n_env + len(FEATURES),)
    assert [r for *_, r in on] == [r for *_, r in off]  # the same episode
    for (a, _, _), (b, _, _) in zip(on, off, strict=True):
        assert a[: b.size].tobytes() == b.tobytes()
        assert a.size == b.size + N * on_env.residual_spec.max_children
    # the layout a model trained before records (the shipped chooser's) is still this code's
    cfg = yaml.safe_load((ROOT / "models" / "ppo_speech_config.yaml").read_text())
    spec = ResidualSpec(**cfg["residual"])
    assert not spec.child_intents
    assert observation_layout(spec.max_children) == cfg["observation_layout"]
    assert observation_layout(spec.max_children, False) == cfg["observation_layout"]
    with_intents = observation_layout(spec.max_children, True)
    assert with_intents["size"] == cfg["observation_layout"]["size"] + N * spec.max_children
    assert with_intents["signature"] != cfg["observation_layout"]["signature"]


class _Recorder:
    """A neutral observation normaliser that keeps what the network is given."""

    def __init__(self, n: int) -> None:
        self.seen: list[np.ndarray] = []
        self.obs_rms = type("Rms", (), {"mean": np.zeros(n), "var": np.ones(n)})()

    def normalize_obs(self, x: np.ndarray) -> np.ndarray:
        self.seen.append(np.array(x[0]))
        return x


def _policy(spec: ResidualSpec, n_in: int, rng: np.random.Generator | None = None) -> PPOPolicy:
    def draw(*shape: int) -> np.ndarray:
        return rng.normal(size=shape) if rng is not None else np.zeros(shape)

    actor = MlpActor((draw(8, n_in), draw(3, 8)), (draw(8), draw(3)))
    return PPOPolicy(actor, _Recorder(n_in), ResidualLC(spec), decision_hz=500)


def test_a_model_reads_the_same_intent_inputs_at_run_time_as_in_training() -> None:
    env, seen = _choices(True, seed=3)
    policy = _policy(env.residual_spec, seen[0][0].size)
    with pytest.raises(ModelError, match="intent"):  # not yet fitted to the graph it speaks
        policy.act(env.reset(seed=3)[0][: -env.core.n_features])
    speak(policy, None)
    run = _env()
    obs, _ = run.reset(seed=3)
    policy.reset()
    done = False
    while not done:
        obs, _, terminated, truncated, _ = run.step(policy.act(obs))
        done = terminated or truncated
    # the network is given the episode's first observation (it starts the features), then each
    # choice's, as training gives it each choice's
    got = policy.normalizer.seen[1:]  # type: ignore[attr-defined]
    assert len(got) == len(seen) > 3
    for a, (b, _, _) in zip(got, seen, strict=True):
        assert a.tobytes() == b.tobytes()


def test_child_intents_are_checked_and_widened_with_their_children() -> None:
    base = ResidualSpec(
        choice_mode="target", max_children=2, pace_scale=0.0, audio_scale=0.0,
        decision_hz=500, choice="fill", decisions="choices",
    )  # fmt: skip
    with pytest.raises(ConfigError, match="decisions='choices'"):
        ResidualSpec(child_intents=True)
    with pytest.raises(ConfigError, match="true or false"):
        replace(base, child_intents=1)  # type: ignore[arg-type]
    spec = replace(base, child_intents=True)
    n_old = observation_layout(2, True)["size"]
    assert ResidualLC(spec).n_features == len(FEATURES) + 2 * N
    policy = _policy(spec, n_old, np.random.default_rng(0))
    x = np.random.default_rng(1).uniform(-1, 1, n_old)
    before = policy.model(x)
    grown = widened_inputs(2, 4, True)
    assert [at for at, _ in grown] == sorted((at for at, _ in grown), reverse=True)
    policy._widen(4)
    assert policy.model.n_inputs == observation_layout(4, True)["size"]
    wide = x
    for at, n in grown:  # any values on the new inputs: the same action
        wide = np.insert(wide, [at] * n, np.random.default_rng(at).uniform(-1, 1, n))
    np.testing.assert_array_equal(policy.model(wide), before)
    assert policy.normalizer.obs_rms.mean.size == wide.size
