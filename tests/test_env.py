"""LangCtrl-v0: API checks, determinism, bad input, and the paper's controller at 500 Hz."""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env as gym_check_env

import langenv
from langenv.control.pacing import AlignerGains, PaceLimits, optimal_paces
from langenv.env import LangCtrlEnv
from langenv.errors import ActionError, ConfigError, PhraseGraphError
from policies import load_policy

SESSIONS = Path(__file__).resolve().parents[2] / "shared" / "sessions"


def zero_user(t: float, v: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.zeros(3)


def resisting_user(t: float, v: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Pushes 12 N against the path between 2 s and 5 s."""
    return -12.0 * b if 2.0 <= t < 5.0 else np.zeros(3)


def run(env: gym.Env, policy, seed: int = 0, **reset_kw):  # type: ignore[no-untyped-def]
    obs, info = env.reset(seed=seed, **reset_kw)
    infos, rewards = [info], []
    done = False
    while not done:
        obs, r, term, trunc, info = env.step(policy.act(obs))
        assert env.observation_space.contains(obs)
        infos.append(info)
        rewards.append(r)
        done = term or trunc
    return infos, rewards, term


@pytest.mark.parametrize("choice_mode", ["target", "scores"])
def test_gymnasium_env_checker(choice_mode: str) -> None:
    env = gym.make(langenv.ENV_ID, choice_mode=choice_mode)
    gym_check_env(env.unwrapped, skip_render_check=True)
    env.close()


def test_sb3_env_checker() -> None:
    from stable_baselines3.common.env_checker import check_env

    env = gym.make(langenv.ENV_ID)
    check_env(env, warn=True)
    env.close()


def _steps_to_truncation(env: gym.Env, limit: int) -> tuple[int, dict]:  # type: ignore[type-arg]
    """Steps of a neutral action until the episode ends (at most ``limit``), and the last info."""
    env.reset(seed=0)
    action = np.zeros(env.action_space.shape, np.float32)
    for k in range(1, limit + 1):
        _, _, term, trunc, info = env.step(action)
        if term or trunc:
            assert trunc and not term
            return k, info
    return limit + 1, info


def test_the_time_limit_is_a_session_length_not_a_step_count() -> None:
    """The registration counts no steps: at the analytic policies' own 500 Hz a session is not
    cut at 3 s (1,500 steps), but at the env's 60 s like at 25 Hz."""
    spec = gym.spec(langenv.ENV_ID)
    assert spec.max_episode_steps is None
    env = gym.make(langenv.ENV_ID, users=zero_user, decision_hz=500)
    assert env.unwrapped.max_seconds == 60.0  # type: ignore[attr-defined]
    steps, info = _steps_to_truncation(env, 1500)
    assert steps == 1501 and not info["motion_done"]  # 3 s: still going


@pytest.mark.parametrize(("hz", "steps"), [(25, 13), (500, 250), (100, 50)])
def test_max_seconds_truncates_at_the_same_time_at_any_rate(hz: int, steps: int) -> None:
    env = gym.make(langenv.ENV_ID, users=zero_user, decision_hz=hz, max_seconds=0.5)
    got, info = _steps_to_truncation(env, 2 * steps)
    assert got == steps  # the first step at or past 0.5 s (25 Hz: 0.52 s)
    assert info["am"] is None and info["time"] == pytest.approx(steps / hz)


def test_the_batch_truncates_where_the_single_env_does() -> None:
    from langenv.batch import LangCtrlVectorEnv

    venv = LangCtrlVectorEnv(2, decision_hz=25, max_seconds=0.5, autoreset_mode="Disabled")
    venv.reset(seed=0)
    for k in range(1, 14):
        _, _, term, trunc, _ = venv.step(np.zeros((2, *venv.single_action_space.shape)))
        assert not term.any() and trunc.tolist() == [k == 13] * 2
    venv.close()


def test_run_law_leaves_the_truncating_step_to_python() -> None:
    env = gym.make(langenv.ENV_ID, users=zero_user, decision_hz=500, max_seconds=0.5)
    base: LangCtrlEnv = env.unwrapped  # type: ignore[assignment]
    policy = load_policy("lc-noap")
    env.reset(seed=0)
    taken, trunc, term = 0, False, False
    while not (trunc or term):
        run = base.run_law(policy.pace_law(), max_steps=10_000)
        taken += run.steps
        assert run.last is None and taken < 250
        _, _, term, trunc, _ = env.step(policy.act(base.observation()))
        taken += 1
    assert trunc and taken == 250


@pytest.mark.parametrize("bad", [0, -1.0, float("nan"), "60", True])
def test_max_seconds_refuses_a_bad_length(bad: object) -> None:
    with pytest.raises(ConfigError, match="max_seconds"):
        LangCtrlEnv(max_seconds=bad)  # type: ignore[arg-type]


def test_make_vec() -> None:
    envs = gym.make_vec(langenv.ENV_ID, num_envs=2, vectorization_mode="sync")
    obs, _ = envs.reset(seed=3)
    assert obs.shape == (2, *envs.single_observation_space.shape)
    obs, r, _term, _trunc, _ = envs.step(np.zeros((2, *envs.single_action_space.shape), np.float32))
    assert r.shape == (2,)
    envs.close()


def test_same_seed_same_episode() -> None:
    pol = load_policy("lc")
    pol.decision_hz = 25
    a = run(gym.make(langenv.ENV_ID), pol, seed=7)
    b = run(gym.make(langenv.ENV_ID), pol, seed=7)
    c = run(gym.make(langenv.ENV_ID), pol, seed=8)
    assert [i["time"] for i in a[0]] == [i["time"] for i in b[0]]
    assert a[1] == b[1]
    assert [i["cooperation"] for i in a[0]] != [i["cooperation"] for i in c[0]]


def test_episode_ends_when_speech_and_motion_are_over() -> None:
    env = gym.make(langenv.ENV_ID, users=zero_user)
    infos, rewards, terminated = run(env, load_policy("ac"))
    last = infos[-1]
    assert terminated and last["motion_done"] and last["speech_done"]
    assert math.isclose(last["am"], last["t_speech"] - last["t_motion"])
    assert 10.0 <= last["t_motion"] <= 12.5  # nominal exercise time, no resistance
    # weighted reward terms are reported and add up
    for info, r in zip(infos[1:], rewards, strict=True):
        assert math.isclose(r, info["reward_em"] + info["reward_pace"] + info["reward_am"])
    assert infos[-1]["reward_am"] == pytest.approx(-abs(last["am"]))


def test_reward_weights_scale_terms() -> None:
    pol = load_policy("lc")
    pol.decision_hz = 25
    a, _, _ = run(gym.make(langenv.ENV_ID, users=resisting_user), pol)
    b, _, _ = run(gym.make(langenv.ENV_ID, users=resisting_user, w_em=2.0, w_am=0.0), pol)
    assert b[5]["reward_em"] == pytest.approx(2.0 * a[5]["reward_em"])
    assert b[-1]["reward_am"] == 0.0 and a[-1]["reward_am"] < 0.0


def test_lc_at_500hz_is_the_papers_controller() -> None:
    """Integrate the paper's pace laws directly on the logged ETCs and cooperation."""
    env = gym.make(langenv.ENV_ID, users=resisting_user, decision_hz=500, max_episode_steps=30_000)
    infos, _, _ = run(env, load_policy("lc"))
    gains = AlignerGains()
    dt = 0.002
    p = a = 1.0
    err_p = err_a = 0.0
    for prev, cur in itertools.pairwise(infos):
        p_star, a_star = optimal_paces(prev["t_x"], prev["t_a"])
        p = min(1.4, max(0.6, p + dt * 6.0 * (p_star - p)))
        da = gains.k_a * (a_star - a) - gains.k_c * (1.0 - prev["cooperation"])
        a = min(1.4, max(0.6, a + dt * da))
        err_p = max(err_p, abs(p - cur["p"]))
        err_a = max(err_a, abs(a - cur["a"]))
    assert err_p < 1e-4 and err_a < 1e-4
    # the paper's slows: resistance lowered the audio pace
    assert min(i["a"] for i in infos) < 0.9


def test_target_choice_at_zero_is_the_papers_rule() -> None:
    # the study's graph: one horizon, the whole motion (a graph marked with legs: tests/test_legs)
    env = gym.make(
        langenv.ENV_ID,
        users=resisting_user,
        phrase_graph="study",
        decision_hz=500,
        max_episode_steps=30_000,
    )
    base: LangCtrlEnv = env.unwrapped  # type: ignore[assignment]
    obs, _ = env.reset(seed=0)
    pol = load_policy("lc")
    choices = 0
    done = False
    while not done:
        before = base.speech.phrase
        obs, _, term, trunc, info = env.step(pol.act(obs))
        after = base.speech.phrase
        kids = base.graph.children(before) if before else ()
        if after != before and len(kids) > 1:
            choices += 1
            # the choice is made inside the tick with the t_x of that tick (reported in info)
            assert after == base.graph.choose(before, info["t_x"])
        done = term or trunc
    assert choices >= 1


def test_bad_arguments_raise_clear_errors(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match="decision_hz"):
        LangCtrlEnv(decision_hz=7)
    with pytest.raises(ConfigError, match="choice_mode"):
        LangCtrlEnv(choice_mode="dice")  # type: ignore[arg-type]
    with pytest.raises(ConfigError, match="users"):
        LangCtrlEnv(users="ghost")
    with pytest.raises(ConfigError, match="session"):
        LangCtrlEnv(users="replay")
    with pytest.raises(ConfigError, match="w_em"):
        LangCtrlEnv(w_em=float("nan"))
    bad = tmp_path / "g.yaml"
    bad.write_text("start: a\nphrases:\n  a:\n    text: hi\n    next: [b]\n")
    with pytest.raises(PhraseGraphError, match=r"g\.yaml"):
        LangCtrlEnv(phrase_graph=bad)


@pytest.mark.parametrize(
    "action", [[np.nan, 0, 0], [0, np.inf, 0], [1.5, 0, 0], [0, 0, -2.0], [0, 0]]
)
def test_bad_actions_raise(action: list[float]) -> None:
    env = LangCtrlEnv()
    env.reset(seed=0)
    with pytest.raises(ActionError, match="action"):
        env.step(np.asarray(action, np.float32))


def test_scores_mode_never_picks_an_invalid_child() -> None:
    env = gym.make(langenv.ENV_ID, choice_mode="scores", users=zero_user)
    base: LangCtrlEnv = env.unwrapped  # type: ignore[assignment]
    env.reset(seed=0)
    rng = np.random.default_rng(0)
    done = False
    while not done:
        act = rng.uniform(-1, 1, env.action_space.shape).astype(np.float32)
        _obs, _, term, trunc, _ = env.step(act)
        done = term or trunc
    path = base.speech.path
    for u, v in itertools.pairwise(path):
        assert v in base.graph.children(u)


@pytest.mark.skipif(not SESSIONS.is_dir(), reason="recorded sessions not available")
@pytest.mark.parametrize(
    ("limits", "u", "in_range"),
    [
        (PaceLimits(p_max=1.6), 1.0, lambda p: p > 1.55),
        (PaceLimits(p_min=0.3, a_min=0.3), -1.0, lambda p: p < 0.35),
    ],
)
def test_wider_pace_limits_run_whole_episodes(
    limits: PaceLimits, u: float, in_range: Callable[[float], bool]
) -> None:
    """The pace bounds have one source, the env's PaceLimits: a pace beyond SPEC's [0.6, 1.4]
    that they allow drives the arm for whole episodes (it once stopped mid-episode with
    "VariableAdmittance.step: p must lie in [0.6, 1.4], got 1.402")."""
    env = gym.make(langenv.ENV_ID, paces=limits, max_episode_steps=6000)
    for seed in (0, 1):
        env.reset(seed=seed)
        paces = []
        while True:
            _, _, term, trunc, info = env.step(np.array([u, u, 0.0], np.float32))
            paces.append(info["p"])
            if term or trunc:
                break
        assert term and info["safety_stop"] is None and info["am"] is not None
        assert any(in_range(p) for p in paces)
        assert limits.p_min <= min(paces) and max(paces) <= limits.p_max


@pytest.mark.skipif(not SESSIONS.is_dir(), reason="recorded sessions not available")
def test_replay_user_reproduces_recorded_cooperation() -> None:
    csv = SESSIONS / "u3_lc.csv"
    env = gym.make(langenv.ENV_ID, users="replay", session=csv, decision_hz=50)
    pol = load_policy("lc")
    infos, _, _ = run(env, pol)
    data = np.genfromtxt(csv, delimiter=",", names=True)
    t = np.array([i["time"] for i in infos])
    c = np.array([i["cooperation"] for i in infos])
    mask = t <= data["t"][-1]
    rmse = float(
        np.sqrt(np.mean((np.interp(t[mask], data["t"], data["cooperation"]) - c[mask]) ** 2))
    )
    assert rmse < 0.05


def test_render_rgb_array(offscreen_gl: None) -> None:
    env = gym.make(langenv.ENV_ID, render_mode="rgb_array", width=160, height=120)
    env.reset(seed=0)
    frame = env.render()
    assert isinstance(frame, np.ndarray)
    assert frame.shape == (120, 160, 3) and frame.dtype == np.uint8
    assert frame.std() > 1.0  # not a blank image
    env.close()


@pytest.mark.parametrize(
    ("kwargs", "name"),
    [
        ({"decision_hz": True}, "decision_hz"),
        ({"decision_hz": 25.0}, "decision_hz"),
        ({"w_am": "1"}, "w_am"),
        ({"w_pace": None}, "w_pace"),
        ({"width": "wide"}, "width"),
        ({"render_mode": "human"}, "render_mode"),
        ({"safety": {"max_speed": 0.3}}, "safety"),
    ],
)
def test_bad_argument_types_are_named(kwargs: dict[str, object], name: str) -> None:
    with pytest.raises(ConfigError, match=name):
        gym.make(langenv.ENV_ID, **kwargs)


def test_human_render_mode_says_how_to_get_a_window() -> None:
    with pytest.raises(ConfigError, match="HumanRendering"):
        gym.make(langenv.ENV_ID, render_mode="human")


@pytest.mark.parametrize(
    ("action", "fragment"),
    [
        ("0.5", "got a str"),
        ({"p": 0.0}, "got a dict"),
        (None, "action is None"),
        (np.zeros((1, 3), np.float32), "got shape (1, 3)"),
        ([[0.0, 0.0, 0.0]], "got shape (1, 3)"),
        ([0.0, "fast", 0.0], "numbers"),
        (object(), "numbers"),
    ],
)
def test_malformed_actions_are_named(action: object, fragment: str) -> None:
    env = LangCtrlEnv()
    env.reset(seed=0)
    with pytest.raises(ActionError) as info:
        env.step(action)  # type: ignore[arg-type]
    assert fragment in str(info.value)


def test_max_children_pads_the_observation_to_one_layout() -> None:
    """Envs of graphs with different out-degrees share a layout when given one ``max_children``;
    the extra child blocks are empty, and fewer than the graph needs is refused by name."""
    from langenv.env import LangCtrlEnv
    from langenv.errors import ConfigError
    from langenv.task.observation import CHILD_FIELDS, observation_size

    plain = LangCtrlEnv(phrase_graph="study")
    wide = LangCtrlEnv(phrase_graph="study", max_children=plain.max_children + 2)
    assert wide.observation_space.shape == (observation_size(plain.max_children + 2),)
    a, _ = plain.reset(seed=3)
    b, _ = wide.reset(seed=3)
    assert np.array_equal(b[: a.size], a)
    extra = b[a.size :]
    assert extra.size == 2 * CHILD_FIELDS
    assert np.array_equal(extra, np.tile(extra[:CHILD_FIELDS], 2))  # two empty blocks
    with pytest.raises(ConfigError, match="max_children"):
        LangCtrlEnv(phrase_graph="study", max_children=plain.max_children - 1)
