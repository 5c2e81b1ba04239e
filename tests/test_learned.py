"""The learned aligner's residual map, wrappers and PPOPolicy loading (policies/learned.py)."""

from __future__ import annotations

import shutil
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import langenv
from langenv.control.pacing import command_from_action
from langenv.errors import ConfigError
from langenv.exercise import speak
from langenv.task import observation as ob
from langenv.task.observation import ChildField, Obs
from policies import load_policy
from policies.analytic import LanguageController
from policies.learned import FEATURES, PPOPolicy, ResidualLC, ResidualSpec, model_files
from train.wrappers import AlignmentReward, ResidualLCWrapper, SeedCycle

REPO = Path(__file__).resolve().parents[1]
SHIPPED = REPO / "models" / "ppo_aligner.zip"  # the shipped learned aligner


def _make(**kw: Any) -> Any:
    kw.setdefault("decision_hz", 50)
    kw.setdefault("max_episode_steps", 3000)
    return gym.make(langenv.ENV_ID, **kw)


def _obs(t_x: float, t_a: float, coop: float, mids: list[float], n_children: int) -> np.ndarray:
    """A synthetic observation with the fields the residual map reads."""
    obs = np.zeros(ob.observation_size(n_children), np.float32)
    obs[Obs.T_X], obs[Obs.T_A] = ob.encode_seconds(t_x), ob.encode_seconds(t_a)
    obs[Obs.COOPERATION] = ob.encode_fraction(coop)
    for k in range(n_children):
        valid = k < len(mids)
        obs[ob.child_index(k, ChildField.VALID)] = ob.encode_flag(valid)
        if valid:
            obs[ob.child_index(k, ChildField.T_MIN)] = ob.encode_seconds(mids[k] - 0.5)
            obs[ob.child_index(k, ChildField.T_MAX)] = ob.encode_seconds(mids[k] + 0.5)
    return obs


def _papers_choice_as_scores(obs: np.ndarray, env: Any) -> np.ndarray:
    """Scores that make the "scores" env pick the paper's child: +1 for the valid child whose
    mid-length is closest to ``t_x``, -1 for the others (read from the observation alone)."""
    t_x = max(0.0, ob.seconds(obs, Obs.T_X))
    dist = np.full(env.max_children, np.inf)
    for k in range(env.max_children):
        block = ob.child(obs, k)
        if block is not None and block[0]:
            dist[k] = abs(t_x - 0.5 * (block[1] + block[2]))
    scores = -np.ones(env.max_children, np.float32)
    scores[int(np.argmin(dist))] = 1.0
    return scores


@pytest.mark.parametrize(
    ("mode", "terminal", "k_em"),
    [("target", 0.0, 0.0), ("scores", 0.0, 0.0), ("target", 1.0, 0.0), ("target", 1.0, 1.0)],
)
def test_zero_residual_is_lc_on_the_env(mode: str, terminal: float, k_em: float) -> None:
    """At r = 0 the wrapped env follows exactly its base's trajectory (LC, LC with a terminal
    phase, or with the misalignment feedback too), step by step."""
    wrapped = ResidualLCWrapper(_make(choice_mode=mode), terminal=terminal, k_em=k_em)
    plain = _make(choice_mode=mode)
    lc = LanguageController(decision_hz=50, terminal=terminal, k_em=k_em)
    lc.action_dim = plain.action_space.shape[0]
    lc.reset()
    w_obs, _ = wrapped.reset(seed=7)
    obs, _ = plain.reset(seed=7)
    assert w_obs.shape == (plain.observation_space.shape[0] + len(FEATURES),)
    assert np.array_equal(w_obs[: obs.size], obs)
    for _ in range(2000):
        act = lc.act(obs)
        if mode == "scores":  # the paper's rule, as scores the plain env reads
            act = np.concatenate([act[:2], _papers_choice_as_scores(obs, plain.unwrapped)])
        w_obs, _, w_term, _, w_info = wrapped.step(np.zeros(wrapped.residual_spec.action_dim))
        obs, _, term, _, info = plain.step(act)
        assert w_info["phrase"] == info["phrase"]
        assert w_info["p"] == info["p"] and w_info["a"] == info["a"]
        assert w_term == term
        if term:
            break
    assert wrapped.observation_space.contains(w_obs)


@settings(max_examples=60, deadline=None)
@given(
    t_x=st.floats(0.0, 35.0),
    mids=st.lists(st.floats(1.0, 30.0), min_size=2, max_size=6, unique=True),
)
def test_scores_prior_picks_the_papers_child(t_x: float, mids: list[float]) -> None:
    """With r = 0 the highest-scoring valid child is the one with the closest mid-length."""
    spec = ResidualSpec(choice_mode="scores", max_children=6)
    core = ResidualLC(spec)
    core.start(_obs(t_x, 5.0, 1.0, mids, 6))
    act = core.action(np.zeros(spec.action_dim))
    chosen = int(np.argmax(act[2 : 2 + len(mids)]))
    dist = [abs(t_x - m) for m in mids]
    assert dist[chosen] == pytest.approx(min(dist), abs=1e-4)


@settings(max_examples=80, deadline=None)
@given(
    t_x=st.floats(0.0, 30.0),
    t_a=st.floats(0.0, 30.0),
    coop=st.floats(0.0, 1.0),
    r=st.lists(st.floats(-1.0, 1.0), min_size=3, max_size=3),
)
def test_residual_moves_pace_commands_within_bounds(
    t_x: float, t_a: float, coop: float, r: list[float]
) -> None:
    """Actions stay in [-1, 1]; a larger correction never lowers a pace command."""
    spec = ResidualSpec(pace_scale=0.3, choice_scale=0.5)
    core = ResidualLC(spec)
    core.start(_obs(t_x, t_a, coop, [5.0], 1))
    act = core.action(np.array(r))
    assert act.dtype == np.float32 and np.all(np.abs(act) <= 1.0)
    assert act[2] == pytest.approx(np.clip(0.5 * r[2], -1, 1), abs=1e-6)
    base = core.action(np.zeros(3))
    for i in (0, 1):
        cmd, cmd0 = (
            command_from_action(float(act[i]), 1.4),
            command_from_action(float(base[i]), 1.4),
        )
        if r[i] >= 0:
            assert cmd >= cmd0 - 1e-6
        else:
            assert cmd <= cmd0 + 1e-6


@pytest.mark.parametrize("audio_scale", [None, 0.1])
def test_audio_scale_bounds_the_audio_correction_only(audio_scale: float | None) -> None:
    """``audio_scale`` limits the audio command's change; the physical one keeps ``pace_scale``."""
    spec = ResidualSpec(pace_scale=0.3, audio_scale=audio_scale)
    core = ResidualLC(spec)
    core.start(_obs(8.0, 9.0, 1.0, [5.0], 1))
    base, act = core.action(np.zeros(3)), core.action(np.array([-1.0, -1.0, 0.0]))
    d_p = command_from_action(float(base[0]), 1.4) - command_from_action(float(act[0]), 1.4)
    d_a = command_from_action(float(base[1]), 1.4) - command_from_action(float(act[1]), 1.4)
    assert d_p == pytest.approx(0.3, abs=1e-5)
    assert d_a == pytest.approx(0.3 if audio_scale is None else 0.1, abs=1e-5)
    assert spec.audio_gain == pytest.approx(d_a, abs=1e-5)


def test_terminal_phase_switches_the_pace_correction_off() -> None:
    """With a terminal base, the pace correction acts before the terminal phase, not in it."""
    core = ResidualLC(ResidualSpec(terminal=1.0))
    push = np.array([1.0, 1.0, 1.0])
    core.start(_obs(5.0, 5.5, 1.0, [5.0], 1))
    assert not np.array_equal(core.action(push)[:2], core.action(np.zeros(3))[:2])
    core.observe(_obs(0.8, 0.9, 1.0, [5.0], 1))
    zero, act = core.action(np.zeros(3)), core.action(push)
    assert np.array_equal(act[:2], zero[:2]) and act[2] != zero[2]
    assert np.array_equal(core.observe(_obs(0.78, 0.88, 1.0, [5.0], 1))[-2:], np.zeros(2))


def test_zero_pace_scales_leave_the_paces_to_the_base() -> None:
    """pace_scale = audio_scale = 0: only the phrase choice is learned; the paces are the base's
    and the ignored pace outputs are not fed back as features."""
    choice_only = ResidualLC(ResidualSpec(pace_scale=0.0, audio_scale=0.0, k_em=1.0))
    base = ResidualLC(ResidualSpec(k_em=1.0))
    obs = _obs(6.0, 4.0, 0.7, [3.0, 8.0], 2)
    choice_only.start(obs)
    base.start(obs)
    r = np.array([1.0, -1.0, 0.6])
    got = choice_only.action(r)
    want = base.action(np.array([0.0, 0.0, 0.6]))
    np.testing.assert_allclose(got, want, atol=1e-6)
    assert got[2] == pytest.approx(0.3)
    assert np.array_equal(choice_only.observe(obs)[-2:], np.zeros(2))


def test_gate_leaves_an_aligned_base_alone() -> None:
    """gate_em: while |t_a - t_x| is below it, any correction gives the base's action exactly
    (paces and phrase choice); once the misalignment reaches it, the correction acts."""
    gated = ResidualLC(ResidualSpec(k_em=1.0, gate_em=0.05))
    base = ResidualLC(ResidualSpec(k_em=1.0))
    push = np.array([1.0, -1.0, 0.6])
    for t_a, acts in ((6.03, False), (6.2, True)):
        obs = _obs(6.0, t_a, 0.7, [3.0, 8.0], 2)
        gated.start(obs)
        base.start(obs)
        got, zero = gated.action(push), base.action(np.zeros(3))
        assert np.array_equal(got, zero) != acts
        if acts:
            np.testing.assert_array_equal(got, base.action(push))
        else:
            assert np.array_equal(gated.observe(obs)[-2:], np.zeros(2))


def test_deadband_zeroes_small_corrections_and_rescales_the_rest() -> None:
    """deadband d: |r| <= d acts as 0; r acts as sign(r) (|r| - d) / (1 - d), up to 1 at |r| = 1."""
    banded = ResidualLC(ResidualSpec(k_em=1.0, deadband=0.2))
    plain = ResidualLC(ResidualSpec(k_em=1.0))
    obs = _obs(6.0, 6.5, 0.7, [3.0, 8.0], 2)
    banded.start(obs)
    plain.start(obs)
    np.testing.assert_array_equal(
        banded.action(np.array([0.2, -0.15, 0.1])), plain.action(np.zeros(3))
    )
    np.testing.assert_allclose(
        banded.action(np.array([0.6, -1.0, -0.4])), plain.action(np.array([0.5, -1.0, -0.25]))
    )


def test_residual_spec_and_core_reject_bad_input() -> None:
    with pytest.raises(ConfigError, match="choice_mode"):
        ResidualSpec(choice_mode="argmax")  # type: ignore[arg-type]
    with pytest.raises(ConfigError, match="pace_scale"):
        ResidualSpec(pace_scale=-0.1)
    with pytest.raises(ConfigError, match="pace_scale"):
        ResidualSpec(pace_scale="0.5")  # type: ignore[arg-type]
    with pytest.raises(ConfigError, match="choice_scale"):
        ResidualSpec(choice_scale=0.0)
    with pytest.raises(ConfigError, match="audio_scale"):
        ResidualSpec(audio_scale=float("nan"))
    with pytest.raises(ConfigError, match="terminal"):
        ResidualSpec(terminal=-1.0)
    with pytest.raises(ConfigError, match="k_em"):
        ResidualSpec(k_em=float("inf"))
    with pytest.raises(ConfigError, match="gate_em"):
        ResidualSpec(gate_em=-0.01)
    with pytest.raises(ConfigError, match="deadband"):
        ResidualSpec(deadband=1.0)
    core = ResidualLC(ResidualSpec())
    with pytest.raises(ConfigError, match="before start"):
        core.action(np.zeros(3))
    core.start(_obs(5.0, 5.0, 1.0, [5.0], 1))
    with pytest.raises(ConfigError, match="shape"):
        core.action(np.zeros(4))
    with pytest.raises(ConfigError, match="finite"):
        core.action(np.array([np.nan, 0.0, 0.0]))
    with pytest.raises(ConfigError, match="choice_mode"):
        ResidualLCWrapper(_make(choice_mode="target"), choice_mode="scores")


def test_motion_rate_feature_tracks_resistance() -> None:
    """Time lost and motion rate: zero without resistance, negative rate when the person resists."""
    resist = ResidualLCWrapper(_make(users=lambda t, v, b: -30.0 * b))
    free = ResidualLCWrapper(_make(users=lambda t, v, b: 0.0 * b))
    n_env = resist.env.observation_space.shape[0]
    i_rate, i_lost = n_env + FEATURES.index("motion_rate_avg"), n_env + FEATURES.index("time_lost")
    for env, sign in ((resist, -1), (free, 0)):
        env.reset(seed=0)
        for _ in range(100):
            obs, *_ = env.step(np.zeros(env.residual_spec.action_dim))
        if sign < 0:
            assert obs[i_rate] < -0.5 and obs[i_lost] > 0.1
        else:
            assert abs(obs[i_rate]) < 0.1 and abs(obs[i_lost]) < 0.05


def test_alignment_reward_terms() -> None:
    env = AlignmentReward(_make(w_em=0.0, w_pace=0.0, w_am=0.0), w_em=1.0, w_adev=1.0)
    env.reset(seed=3)
    total = 0.0
    terms = 0.0
    for _ in range(3000):
        _, r, term, trunc, info = env.step(np.array([0.0, -0.2, 0.0], np.float32))
        total += r
        terms += info["reward_em_base"] + info["reward_adev"] + info["reward_am_fine"]
        assert info["reward_em_base"] <= 0.0 and info["reward_adev"] <= 0.0
        if term or trunc:
            break
    assert term
    assert info["reward_am_fine"] == pytest.approx(-np.log1p(abs(info["am"]) / 0.02))
    assert total == pytest.approx(terms)
    with pytest.raises(ConfigError, match="w_em"):
        AlignmentReward(_make(), w_em=-1.0)


def test_seed_cycle_repeats_users() -> None:
    env = SeedCycle(_make(), seeds=[11, 12])
    first = [env.reset()[0] for _ in range(4)]
    assert np.array_equal(first[0], first[2]) and np.array_equal(first[1], first[3])
    with pytest.raises(ConfigError, match="seeds"):
        SeedCycle(_make(), seeds=[])


def test_model_files_names() -> None:
    z, n, c = model_files("models/x.zip")
    assert (z.name, n.name, c.name) == ("x.zip", "x_vecnormalize.pkl", "x_config.yaml")
    assert model_files("models/x") == (z, n, c)


def test_load_missing_files_name_the_path(tmp_path: Path) -> None:
    with pytest.raises(FileNotFoundError, match=r"nope\.zip"):
        PPOPolicy.load(tmp_path / "nope.zip")
    with pytest.raises(FileNotFoundError, match=r"nope\.zip"):
        load_policy(f"ppo:{tmp_path / 'nope.zip'}")


def test_trained_model_acts_deterministically(tiny_ppo_models: tuple[Path, ...]) -> None:
    policy = load_policy(f"ppo:{tiny_ppo_models[0]}")
    assert isinstance(policy, PPOPolicy)
    graph = speak(policy).ref  # fits the model to the graph it speaks: before env_kwargs
    env = _make(phrase_graph=graph, decision_hz=policy.decision_hz, **policy.env_kwargs)
    assert policy.decision_hz == env.unwrapped.decision_hz
    obs, _ = env.reset(seed=5)
    policy.reset()
    acts = [policy.act(obs)]
    for _ in range(20):
        obs, *_ = env.step(acts[-1])
        acts.append(policy.act(obs))
    policy.reset()
    assert np.array_equal(policy.act(env.reset(seed=5)[0]), acts[0])
    assert all(env.action_space.contains(a) for a in acts)


@pytest.mark.parametrize("broken", ["zip", "pkl", "yaml"])
def test_corrupt_files_raise_value_error_naming_them(
    tiny_ppo_models: tuple[Path, ...], tmp_path: Path, broken: str
) -> None:
    z, n, c = model_files(tmp_path / "m.zip")
    for src, dst in zip(model_files(tiny_ppo_models[0]), (z, n, c), strict=True):
        shutil.copy(src, dst)
    target = {"zip": z, "pkl": n, "yaml": c}[broken]
    target.write_bytes(b"\x00garbage: [" if broken == "yaml" else b"not a real file")
    with pytest.raises(ValueError, match=target.name):
        PPOPolicy.load(z)


def test_shipped_model_corrects_paces_and_phrase_choice() -> None:
    """The shipped model acts on p, a and the phrase choice on top of its analytic base (LC with
    lc-em's feedback and the terminal phase): over a whole session all three differ from it."""
    policy = load_policy(f"ppo:{SHIPPED}")
    assert isinstance(policy, PPOPolicy)
    spec = policy.residual.spec
    assert spec.pace_scale > 0 and spec.audio_gain > 0
    assert (spec.k_em, spec.terminal) == (1.0, 1.0)
    graph = speak(policy, override="study").ref  # the graph it was trained on: 6 choices
    env = _make(phrase_graph=graph, decision_hz=policy.decision_hz, **policy.env_kwargs)
    base = LanguageController(action_dim=3, terminal=spec.terminal, k_em=spec.k_em)
    obs, _ = env.reset(seed=11)
    policy.reset()
    base.reset()
    acts, wants = [], []
    for _ in range(policy.decision_hz * 60):
        act, want = policy.act(obs), base.act(obs)
        acts.append(act)
        wants.append(want)
        obs, _, term, trunc, _ = env.step(act)
        if term or trunc:
            break
    assert term
    diff = np.abs(np.array(acts) - np.array(wants)).max(axis=0)
    assert np.all(diff > 0.01), diff  # the network moves p, a and the phrase target
