"""The env speaking the default graph: pause vertices in the observation, info and actions."""

from __future__ import annotations

from pathlib import Path

import gymnasium as gym
import numpy as np

import langenv
from langenv.task import observation as ob
from langenv.task.observation import Obs
from policies.analytic import make_analytic


def episode(u_choice: float, seed: int = 3) -> tuple[list[dict], list[np.ndarray], object]:
    env = gym.make(langenv.ENV_ID, phrase_graph="default", decision_hz=25, max_episode_steps=1500)
    policy = make_analytic("lc", decision_hz=25)
    obs, info = env.reset(seed=seed)
    policy.reset()
    infos, observations = [info], [obs]
    done = False
    while not done:
        action = policy.act(obs)
        action[2] = u_choice
        obs, _, term, trunc, info = env.step(action)
        infos.append(info)
        observations.append(obs)
        done = term or trunc
    return infos, observations, env.unwrapped


def test_lc_waits_in_pauses_that_make_the_speech_end_with_the_motion() -> None:
    infos, observations, base = episode(0.0)
    graph = base.graph  # type: ignore[attr-defined]
    paused = [
        (i, o) for i, o in zip(infos, observations, strict=True) if i["phrase"] in graph.pauses
    ]
    assert paused, "LC never entered a pause"
    for info, obs in paused:
        assert info["in_pause"] and ob.flag(obs.tolist(), Obs.IN_PAUSE)
    # inside a pause the speech plan meets the motion's: t_a = t_x wherever the bounds allow
    gaps = [abs(i["t_a"] - i["t_x"]) for i, _ in paused]
    assert float(np.median(gaps)) < 0.05
    assert abs(infos[-1]["am"]) < 1.0
    speech = base.speech  # type: ignore[attr-defined]
    assert len(speech.pause_lengths) == sum(1 for u in speech.path if u in graph.pauses)
    for u, length in zip(
        (u for u in speech.path if u in graph.pauses), speech.pause_lengths, strict=True
    ):
        lo, hi = graph.slot_range(u)
        assert lo - 1e-9 <= length <= hi + 1e-9


def test_the_target_duration_action_lengthens_or_shortens_the_pauses(tmp_path: Path) -> None:
    """On a graph without choices (its words fixed), the target-duration action sets the pause."""
    graph = tmp_path / "g.yaml"
    graph.write_text(
        "start: a\npause: 0.3\nphrases:\n"
        '  a: {text: "Move your hand away from your body.", next: [p]}\n'
        "  p: {pause: [0.2, 10], next: [b]}\n"
        '  b: {text: "And back again.", next: []}\n'
    )

    def pause(u_choice: float) -> float:
        env = gym.make(langenv.ENV_ID, phrase_graph=str(graph), decision_hz=25)
        policy = make_analytic("lc", decision_hz=25)
        obs, _ = env.reset(seed=3)
        while "p" not in env.unwrapped.speech.path:  # type: ignore[attr-defined]
            action = policy.act(obs)
            action[2] = u_choice
            obs, *_ = env.step(action)
        return float(env.unwrapped.speech.slot_length)  # type: ignore[attr-defined]

    assert pause(0.5) > pause(0.0) > pause(-0.5)
