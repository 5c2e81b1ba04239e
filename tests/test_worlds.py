"""Training across worlds: the split (langenv.worlds.WorldSplit) and the env that draws worlds."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from langenv.errors import ConfigError
from langenv.worlds import WorldEnv, WorldSplit

SPLIT: dict[str, Any] = {
    "train": ["external_rotation", "shoulder_flexion"],
    "validation": ["shoulder_extension"],
    "test": ["hand_to_mouth", "forearm_rotation"],
    "graphs": {},  # every shipped LC script offers 9 choices (the default graph's pattern)
}


def _split(**over: Any) -> WorldSplit:
    return WorldSplit.from_dict({**SPLIT, **over})


@pytest.mark.parametrize(
    ("over", "match"),
    [
        ({"validation": ["shoulder_flexion"]}, "shoulder_flexion in both train and validation"),
        ({"test": ["hand_to_mouth"]}, "at least two"),
        ({"train": []}, "non-empty"),
        ({"test_users": [900010, 900100]}, "validation_users and test_users overlap"),
        ({"train_users": [5, 5]}, "train_users"),
        ({"holdout": ["x"]}, "unknown key"),
        ({"variation": {"p_drop": 2.0}}, "variation"),
        ({"perturbations": {"weights": {"sneeze": 1.0}}}, "perturbations"),
    ],
)
def test_bad_split_is_named(over: dict[str, Any], match: str) -> None:
    with pytest.raises(ConfigError, match=match):
        _split(**over)


def test_missing_role_is_named() -> None:
    with pytest.raises(ConfigError, match="missing test"):
        WorldSplit.from_dict({"train": ["a"], "validation": ["b"]})


def test_round_trip_and_pairs() -> None:
    split = _split()
    assert WorldSplit.from_dict(split.to_dict()) == split
    pairs = split.pairs("test", 5)
    assert pairs == [
        ("hand_to_mouth", 5_000_000),
        ("forearm_rotation", 5_000_000),
        ("hand_to_mouth", 5_000_001),
        ("forearm_rotation", 5_000_001),
        ("hand_to_mouth", 5_000_002),
    ]
    with pytest.raises(ConfigError, match="users"):
        split.pairs("validation", 49)


def test_graphs_of_unequal_choices_are_refused() -> None:
    split = _split(graphs={"external_rotation": "study"})  # the study's graph: 6 choices
    with pytest.raises(ConfigError, match="external_rotation: 6"):
        split.check()


def _run(env: WorldEnv, episodes: int) -> list[dict[str, Any]]:
    worlds = []
    env.reset(seed=4)
    for _ in range(episodes):
        worlds.append(dict(env.world))
        done = False
        while not done:
            _, _, term, trunc, _ = env.step(np.zeros(3, np.float32))
            done = term or trunc
        env.reset()
    return worlds


def test_training_worlds_are_drawn_from_the_train_split_and_seeded() -> None:
    split = _split()
    kwargs = {"decision_hz": 25, "max_episode_steps": 1500}
    a = _run(WorldEnv(split, "train", kwargs), 6)
    b = _run(WorldEnv(split, "train", kwargs), 6)
    assert a == b
    lo, hi = split.users("train")
    assert all(w["exercise"] in split.train and lo <= w["user_seed"] < hi for w in a)
    assert len({w["graph_t_max"] for w in a}) == 6  # every episode a new variant


def test_validation_cycles_its_pairs_on_the_scripts() -> None:
    split = _split()
    env = WorldEnv(split, "validation", {"decision_hz": 25}, n_episodes=2)
    seen = [env.reset()[1]["world"] for _ in range(3)]
    assert [(w["exercise"], w["user_seed"]) for w in seen] == [
        ("shoulder_extension", 900_000),
        ("shoulder_extension", 900_001),
        ("shoulder_extension", 900_000),
    ]
    graph = env.envs["shoulder_extension"].unwrapped.graph
    assert seen[0]["graph_t_max"] == graph.speech_range()[1]  # the script itself
