"""The learned coach's recipe: ChoicePoints with people who listen (configs/ppo_coach.yaml)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from eval.compare import Job, run_episode
from langenv.errors import ConfigError
from langenv.users import ListeningParams, ListeningUser
from langenv.users.listening import SOURCES
from langenv.worlds import WorldEnv, WorldSplit
from train.choices import ChoicePoints, listening_ranges

ROOT = Path(__file__).resolve().parents[1]
CONFIG = ROOT / "configs" / "ppo_coach.yaml"


def test_assumptions_are_the_documented_ranges_and_ranges_are_checked() -> None:
    ranges = listening_ranges("assumptions")
    assert ranges == {k: s.range for k, s in SOURCES.items() if s.kind == "assumption"}
    assert listening_ranges(None) is None
    assert listening_ranges({"comply": [0.2, 0.4]}) == {"comply": (0.2, 0.4)}
    for bad, match in (
        ({"nope": [0, 1]}, "unknown field"),
        ({"comply": [0.5]}, r"\[lo, hi\]"),
        ({"comply": [0.6, 0.4]}, "lo <= hi"),
        ({"latency": [0.01, 1.0]}, "latency"),
        ("everything", "'assumptions' or a mapping"),
    ):
        with pytest.raises(ConfigError, match=match):
            listening_ranges(bad)  # type: ignore[arg-type]


def test_a_held_out_person_listens_alike_in_every_evaluation() -> None:
    """The periodic evaluation resets its held-out WorldEnv without a seed: each person's
    listening draw is then seeded by that person's seed, the same in every run and every
    evaluation (it came from an unseeded generator before)."""
    split = WorldSplit.load(CONFIG)

    def draws() -> list[dict[str, float]]:
        world = WorldEnv(split, "validation", {"decision_hz": 500}, 2)
        env = ChoicePoints(world, listening="assumptions")
        out = []
        for _ in range(3):  # the pairs cycle: the third is the first person again
            assert world.next_user_seed is not None
            out.append(env.reset()[1]["listening"])
        return out

    first, second = draws(), draws()
    assert first == second and first[0] == first[2] and first[0] != first[1]
    train = WorldEnv(split, "train", {"decision_hz": 500})
    assert train.next_user_seed is None


def test_each_episode_s_person_listens_with_assumptions_drawn_by_its_seed(tmp_path: Path) -> None:
    """Over a WorldEnv (the recipe's training and validation envs): a ListeningUser of drawn
    parameters per reset, the same for the same seed; the episode is the one eval.compare runs
    for lc-fill with that person (zero correction); the session's length is in the reward."""
    split = WorldSplit.load(CONFIG)
    world = WorldEnv(split, "validation", {"decision_hz": 500}, 2)
    env = ChoicePoints(world, listening="assumptions", w_length=1.0)
    _, info = env.reset(seed=5)
    drawn = ListeningParams(**info["listening"])
    assert isinstance(world.user, ListeningUser) and world.user.listening == drawn
    for name, (lo, hi) in listening_ranges("assumptions").items():  # type: ignore[union-attr]
        assert lo <= getattr(drawn, name) <= hi, name
    assert drawn.nonresponders == ListeningParams().nonresponders  # not an assumption
    seed = world.world["user_seed"]
    done = False
    while not done:
        _, _, terminated, truncated, end = env.step(np.zeros(3, np.float32))
        done = terminated or truncated
    job = Job("lc-fill", f"s{seed}", seed, None, str(tmp_path), False, False, None,
              exercise="shoulder_extension", save_log=False,
              user_model=ListeningUser(drawn))  # fmt: skip
    row = run_episode(job)
    assert end["am"] == pytest.approx(row["am"], abs=1e-12)
    assert end["reward_length"] == pytest.approx(-max(row["t_motion"], row["t_speech"]))
    _, again = env.reset(seed=5)
    assert again["listening"] == info["listening"]
    _, other = env.reset(seed=6)
    assert other["listening"] != info["listening"]
