"""``LangCtrlEnv.run_law``: a pace law applied in compiled code gives, bit for bit, the episode of
the policy that is the law stepping the env; its commands equal the policy's through the
observation and the action (float32 roundings included); bad calls are named."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import langenv
from langenv import env_kernels as ek
from langenv.control.pacing import PaceLaw, PaceLimits, command_from_action
from langenv.control.pacing_kernels import law_commands
from langenv.env import LAW_CHUNK
from langenv.errors import ConfigError
from langenv.exercise import speak
from langenv.task.observation import Obs, encode_flag, encode_fraction, encode_seconds
from langenv.users import SyntheticUser
from langenv.users.synthetic import LogNormal, SyntheticUserParams
from policies.analytic import LanguageController, make_analytic

pytestmark = pytest.mark.portable

FIELDS = (*ek.ROW_FIELDS, "qpos", "f_user")


def _make(policy: LanguageController, **kwargs: Any) -> Any:
    return gym.make(
        langenv.ENV_ID, phrase_graph=speak(policy).ref, decision_hz=500, **kwargs
    ).unwrapped


def _policy_steps(
    policy: LanguageController, seed: int, limit: int, **env_kwargs: Any
) -> dict[str, Any]:
    """Every step taken by the policy: info values and rewards."""
    env = _make(policy, **env_kwargs)
    obs, _ = env.reset(seed=seed)
    rows: dict[str, list[Any]] = {name: [] for name in FIELDS}
    rewards: list[float] = []
    for _ in range(limit):
        obs, reward, terminated, _, info = env.step(policy.act(obs))
        for name in ek.ROW_FIELDS:
            rows[name].append(float(info[name]))
        rows["qpos"].append(env.motion.arm.data.qpos.copy())
        rows["f_user"].append(env.motion.f_user.copy())
        rewards.append(reward)
        if terminated:
            break
    return {**{k: np.array(v) for k, v in rows.items()}, "reward": np.array(rewards)}


def _law_steps(
    policy: LanguageController, seed: int, limit: int, **env_kwargs: Any
) -> tuple[dict[str, Any], int, int]:
    """The same steps, the law's in compiled code and the others the policy's; the number of
    runs of the law and of steps it began that Python finished (``last``)."""
    env = _make(policy, **env_kwargs)
    env.reset(seed=seed)
    law = policy.pace_law()
    assert law is not None
    parts: dict[str, list[Any]] = {name: [] for name in (*FIELDS, "reward")}
    steps, terminated, runs, lasts = 0, False, 0, 0
    while not terminated and steps < limit:
        run = env.run_law(law, limit - steps - 1)
        runs += 1
        for name in FIELDS:
            parts[name].append(run.info[name])
        parts["reward"].append(run.rewards)
        steps += run.steps
        if run.last is not None:
            _, reward, terminated, _, info = run.last
            lasts += 1
        else:
            _, reward, terminated, _, info = env.step(policy.act(env.observation()))
        steps += 1
        for name in ek.ROW_FIELDS:
            parts[name].append(np.array([float(info[name])]))
        parts["qpos"].append(env.motion.arm.data.qpos[None, :].copy())
        parts["f_user"].append(env.motion.f_user[None, :].copy())
        parts["reward"].append(np.array([reward]))
    return {k: np.concatenate(v) for k, v in parts.items()}, runs, lasts


@pytest.mark.parametrize(
    ("name", "seed"), [("lc", 3), ("lc-noap", 4), ("lc-em", 5), ("fill", 6), ("fill", 8)]
)
def test_law_episode_is_the_policy_episode_bit_for_bit(name: str, seed: int) -> None:
    # "fill": the content rule's choices (its phrase action only on the tick a slot ends, the
    # tick run_law hands to the policy) with the rule's own pauses: a law between choices
    policy = (
        LanguageController(name="fill", choice="fill", fill_margin=0.0)
        if name == "fill"
        else make_analytic(name)
    )
    assert isinstance(policy, LanguageController)
    plain = _policy_steps(policy, seed, 30_000)
    fast, runs, _ = _law_steps(policy, seed, 30_000)
    assert plain["time"].size > 4000 and plain["motion_done"][-1] == 1.0
    assert runs > 3  # phrase boundaries were crossed in Python, between runs of the law
    for key, value in plain.items():
        assert fast[key].shape == value.shape, key
        assert np.array_equal(fast[key], value), key


def test_law_run_stops_at_its_step_budget() -> None:
    policy = make_analytic("lc")
    assert isinstance(policy, LanguageController)
    plain = _policy_steps(policy, 7, 700)
    fast, _, _ = _law_steps(policy, 7, 700)
    assert plain["time"].size == fast["time"].size == 700
    assert np.array_equal(plain["t_x"], fast["t_x"]) and np.array_equal(
        plain["reward"], fast["reward"]
    )


def test_a_protective_stop_in_a_law_step_is_the_policys() -> None:
    """A tick of the law's ending in a protective stop: the env finishes that step (``last``)
    as ``env.step`` does."""
    policy = make_analytic("lc")
    assert isinstance(policy, LanguageController)
    pusher = SyntheticUserParams.calibrated(  # pushes at once, hard: a force stop
        count_pmf=(0.0, 1.0),
        p_start_resisting=1.0,
        max_excess=400.0,
        magnitude=LogNormal(300.0, 0.01),
        rise=LogNormal(0.5, 0.01),
    )
    plain = _policy_steps(policy, 0, 30_000, users=SyntheticUser(pusher))
    fast, _, lasts = _law_steps(policy, 0, 30_000, users=SyntheticUser(pusher))
    assert lasts == 1 and plain["motion_done"][-1] == 0.0  # stopped before the motion ended
    for key, value in plain.items():
        assert np.array_equal(fast[key], value), key


def test_without_compiled_ticks_the_law_takes_no_step() -> None:
    policy = make_analytic("lc")
    law = policy.pace_law()  # type: ignore[union-attr]
    assert law is not None
    env = _make(policy, sensor_noise=1.0)  # type: ignore[arg-type]
    env.reset(seed=0)
    assert not env.runs_compiled
    run = env.run_law(law, 10**9)  # nothing allocated for steps it cannot take
    assert run.steps == 0 and run.last is None and run.info["qpos"].shape == (0, 6)
    env = _make(policy)  # type: ignore[arg-type]
    env.reset(seed=0)
    assert env.runs_compiled
    assert env.run_law(law, 10**9).steps <= LAW_CHUNK


def test_compare_episode_with_the_law_is_the_policys(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """``eval.compare`` runs LC's 500 Hz episodes through the law: the same log and row."""
    from eval.compare import Job, run_episode
    from eval.episode import EpisodeLog

    (tmp_path / "law").mkdir()
    (tmp_path / "plain").mkdir()
    law_row = run_episode(Job("lc", "s2", 2, None, str(tmp_path / "law"), False, False, None))
    monkeypatch.setattr(LanguageController, "pace_law", lambda self: None)
    plain_row = run_episode(Job("lc", "s2", 2, None, str(tmp_path / "plain"), False, False, None))
    assert law_row == plain_row
    fast = EpisodeLog.load_npz(tmp_path / "law" / "lc_s2.npz")
    slow = EpisodeLog.load_npz(tmp_path / "plain" / "lc_s2.npz")
    for name in (*ek.ROW_FIELDS[1:], "t", "qpos", "f_user"):
        assert np.array_equal(getattr(fast, name), getattr(slow, name)), name
    assert fast.utterances == slow.utterances and fast.ret == slow.ret


def test_terminal_phase_has_no_law_and_bad_calls_are_named() -> None:
    assert make_analytic("lc-end").pace_law() is None  # type: ignore[union-attr]
    law = make_analytic("lc").pace_law()  # type: ignore[union-attr]
    assert law is not None
    env = gym.make(langenv.ENV_ID, decision_hz=25).unwrapped
    env.reset(seed=0)
    with pytest.raises(ConfigError, match="decision_hz=500"):
        env.run_law(law, 10)
    env = _make(make_analytic("lc"))  # type: ignore[arg-type]
    env.reset(seed=0)
    with pytest.raises(ConfigError, match="PaceLaw"):
        env.run_law("lc", 10)
    with pytest.raises(ConfigError, match="max_steps"):
        env.run_law(law, -1)
    with pytest.raises(ConfigError, match="k_a"):
        PaceLaw(k_c=10.0, k_a=0.0)
    with pytest.raises(ConfigError, match="k_em"):
        PaceLaw(k_c=10.0, k_a=7.0, k_em=float("nan"))
    nothing = env.run_law(law, 0)
    assert nothing.steps == 0 and nothing.last is None and nothing.rewards.shape == (0,)
    assert env.time == 0.0


@settings(max_examples=300, deadline=None)
@given(
    t_x=st.floats(-5.0, 60.0),
    t_a=st.floats(-5.0, 60.0),
    c=st.floats(-0.2, 1.2),
    motion_on=st.booleans(),
    k_em=st.sampled_from([0.0, 1.0, 3.5]),
    p_max=st.sampled_from([1.4, 1.25]),
)
def test_commands_are_the_policys_through_observation_and_action(
    t_x: float, t_a: float, c: float, motion_on: bool, k_em: float, p_max: float
) -> None:
    limits = PaceLimits(p_max=p_max)
    policy = LanguageController(k_em=k_em, limits=limits)
    obs = np.zeros(40, np.float32)
    clip = lambda v: min(1.0, max(-1.0, v))  # noqa: E731
    obs[Obs.T_X] = clip(encode_seconds(t_x))
    obs[Obs.T_A] = clip(encode_seconds(t_a))
    obs[Obs.COOPERATION] = clip(encode_fraction(c))
    obs[Obs.MOTION_DONE] = encode_flag(not motion_on)
    obs[Obs.SPEECH_DONE] = encode_flag(False)
    action = policy.act(obs).tolist()
    env_limits = PaceLimits()  # the env's, which may differ from the policy's
    expected = (
        command_from_action(action[0], env_limits.p_max),
        command_from_action(action[1], env_limits.a_max),
    )
    law = policy.pace_law()
    assert law is not None
    v = law.values()
    got = law_commands(
        v["k_ca"], v["k_em"], v["em_clip"], v["law_p_max"], v["law_a_max"], v["c_min"], 40.0,
        env_limits.p_max, env_limits.a_max, t_x, t_a, c, motion_on,
    )  # fmt: skip
    assert got == expected
