"""The person who listens: parameters, the response's math, what the env tells them, the jobs."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import langenv
from langenv.errors import ConfigError
from langenv.speech.graph import PhraseGraph
from langenv.speech.hearing import Ear
from langenv.speech.phrase import Phrase
from langenv.speech.timeline import SpeechTimeline
from langenv.speech.voice import SLOWEST
from langenv.users import Listener, ListeningParams, ListeningUser, SyntheticUser
from langenv.users.listening import REACTION_S, SOURCES

TANGENT = np.array([0.0, 1.0, 0.0])
V = np.zeros(3)


# ------------------------------------------------------------------------------ the parameters
def test_every_parameter_has_its_source_and_range() -> None:
    names = [f.name for f in dataclasses.fields(ListeningParams)]
    assert list(SOURCES) == names
    doc = ListeningParams.__doc__ or ""
    defaults = ListeningParams()
    for name, src in SOURCES.items():
        assert src.kind in ("published", "fitted", "assumption"), name
        lo, hi = src.range
        assert lo <= getattr(defaults, name) <= hi, name
        assert f"{name}:" in doc and src.note, name
    assert {"latency", "comply"} <= set(names)
    text = (Path(__file__).parents[1] / "docs" / "listening.md").read_text()
    for name in names:
        assert f"| `{name}` |" in text, name


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"latency": 0.1}, "ListeningParams.latency must lie in [0.16, 10], got 0.1"),
        ({"comply": 1.5}, "ListeningParams.comply must lie in [0, 1]"),
        ({"rise": math.nan}, "ListeningParams.rise must be a finite number"),
        ({"guide": True}, "ListeningParams.guide must be a finite number"),
        ({"faster": -1.0}, "ListeningParams.faster must lie in [0, 25]"),
    ],
)
def test_bad_parameters_are_named(kwargs: dict[str, object], message: str) -> None:
    with pytest.raises(ConfigError, match=message.replace("[", r"\[").replace("]", r"\]")):
        ListeningParams(**kwargs)  # type: ignore[arg-type]


def test_key_value_text_sets_the_fields() -> None:
    p = ListeningParams.parse("latency=1.2, comply=0.4")
    assert (p.latency, p.comply, p.rise) == (1.2, 0.4, ListeningParams().rise)
    assert ListeningParams.parse(p.to_text()) == p
    assert ListeningParams.parse("") == ListeningParams()
    for text, message in [
        ("latency", "'latency' is not KEY=VALUE"),
        ("speed=2", "unknown key 'speed'; known: latency, latency_sigma"),
        ("comply=much", "comply='much' is not a number"),
        ("comply=2", "ListeningParams.comply must lie in [0, 1]"),
    ]:
        with pytest.raises(ConfigError, match=message.replace("[", r"\[").replace("]", r"\]")):
            ListeningParams.parse(text)


# ------------------------------------------------------------------------------ the person
def _always(**kw: float) -> ListeningParams:
    """A person who always complies (comply 1, no non-responders), no spread in dead time."""
    base = {"comply": 1.0, "nonresponders": 0.0, "latency_sigma": 0.0}
    return ListeningParams(**{**base, **kw})


def _resisting(user: ListeningUser, force: float = 15.0) -> ListeningUser:
    """The person pushes ``force`` N against the motion throughout (their table replaced)."""
    user._table = [force] * len(user._table)
    return user


def test_without_words_the_person_is_the_synthetic_one_bit_for_bit() -> None:
    for seed in range(6):
        syn, lis = SyntheticUser(), ListeningUser(ListeningParams(follow=0.0))
        syn.reset(np.random.default_rng(seed))
        lis.reset(np.random.default_rng(seed))
        assert syn.episodes == lis.episodes
        for t in np.arange(0.0, 30.0, 0.013):
            assert lis.magnitude(float(t)) == syn.magnitude(float(t))
        lis.hear(1.0, None)  # words without an intent change nothing
        assert lis.magnitude(3.0) == syn.magnitude(3.0)


@settings(max_examples=60, deadline=None)
@given(
    rise=st.floats(0.05, 2.0),
    hold=st.floats(0.5, 20.0),
    latency=st.floats(REACTION_S, 3.0),
    heard=st.floats(0.0, 10.0),
    share=st.floats(0.0, 1.0),
)
def test_a_complied_wording_acts_after_the_dead_time_through_a_first_order_rise(
    rise: float, hold: float, latency: float, heard: float, share: float
) -> None:
    user = ListeningUser(_always(rise=rise, hold=hold, latency=latency, relax=share))
    user.reset(np.random.default_rng(0))
    _resisting(user)
    assert user.dead_time == pytest.approx(latency)
    user.hear(heard, "relax")
    assert user.heard == [(heard, "relax", True)]
    on, off = heard + latency, heard + latency + hold
    for t in np.linspace(0.0, off + 5 * rise, 40):
        m = user.magnitude(float(t))
        level = user.levels()["relax"]
        if t <= on:
            expected = 0.0
        elif t <= off:
            expected = 1.0 - math.exp(-(t - on) / rise)
        else:
            expected = (1.0 - math.exp(-(off - on) / rise)) * math.exp(-(t - off) / rise)
        assert level == pytest.approx(expected, abs=1e-9)
        assert 0.0 <= level <= 1.0
        e = 10.0 * (1.0 - share * level)
        assert m == pytest.approx(5.0 + e if e > 0.0 else 0.0, abs=1e-9)


def test_each_intent_moves_the_force_its_way() -> None:
    p = _always(latency=0.2, rise=0.1, hold=100.0)
    late = 10.0  # the response is complete (1 - e^-98)
    for intent, resisting, expected in [
        ("guide", 15.0, 5.0 + 10.0 * (1 - p.guide)),
        ("encourage", 15.0, 5.0 + 10.0 * (1 - p.encourage)),
        ("relax", 15.0, 5.0 + 10.0 * (1 - p.relax)),
        ("slower", 0.0, 5.0 + p.slower),  # pushes against the motion
        ("faster", 0.0, -(5.0 + p.faster)),  # pushes along it
        ("faster", 15.0, 5.0 + 10.0 - p.faster),
    ]:
        user = ListeningUser(p)
        user.reset(np.random.default_rng(1))
        _resisting(user, resisting)
        user.hear(0.0, intent)
        assert user.magnitude(late) == pytest.approx(expected, rel=1e-9), intent
        f = user.force(late, V, TANGENT)
        assert f == pytest.approx(-expected * TANGENT)


def test_a_second_wording_of_an_intent_extends_its_response() -> None:
    user = ListeningUser(_always(latency=0.5, rise=0.2, hold=2.0))
    user.reset(np.random.default_rng(0))
    user.hear(0.0, "relax")
    user.hear(2.0, "relax")  # heard while the first acts: on until 4.5 s
    user.hear(9.0, "relax")  # after it ended: a new window
    assert user._windows["relax"] == [(0.5, 4.5), (9.5, 11.5)]


def test_a_person_complies_with_their_own_probability() -> None:
    p = ListeningParams(comply=0.6, comply_spread=4.0, nonresponders=0.25)
    people = []
    for seed in range(400):
        user = ListeningUser(p)
        user.reset(np.random.default_rng(seed))
        people.append((user.responder, user.p_comply, user.dead_time))
    responders = [q for r, q, _ in people if r]
    assert abs(1 - len(responders) / 400 - 0.25) < 0.06
    assert abs(np.mean(responders) - 0.6) < 0.04
    assert np.std(responders) > 0.1  # people differ
    assert all(q == 0.0 for r, q, _ in people if not r)
    assert min(d for _, _, d in people) >= REACTION_S
    assert abs(np.mean([d for _, _, d in people]) - p.latency) < 0.05
    # one draw per wording: a person of p_comply complies with about that share
    user = ListeningUser(ListeningParams(comply=0.3, comply_spread=1000.0, nonresponders=0.0))
    user.reset(np.random.default_rng(5))
    for k in range(2000):
        user.hear(0.01 * k, "encourage")
    assert abs(np.mean([c for _, _, c in user.heard]) - user.p_comply) < 0.04


def test_a_non_responder_never_responds() -> None:
    user = ListeningUser(ListeningParams(nonresponders=1.0, follow=1.0))
    user.reset(np.random.default_rng(3))
    _resisting(user)
    user.hear(0.0, "relax")
    user.perceive(0.0, 5.0)
    assert not user.responder and user.heard == [(0.0, "relax", False)]
    assert user.magnitude(5.0) == 15.0


def test_the_person_follows_the_speechs_lead_through_the_dead_time() -> None:
    user = ListeningUser(_always(follow=2.0, latency=0.5, rise=0.3))
    user.reset(np.random.default_rng(0))
    _resisting(user, 0.0)
    assert user.perceives and isinstance(user, Listener)
    dt = 0.002
    for k in range(3000):  # the speech runs 2 s ahead from t = 1 s
        t = k * dt
        user.perceive(t, 2.0 if t >= 1.0 else 0.0)
        m = user.magnitude(t)
        if t < 1.5 - dt:
            assert m == 0.0
    # 4.5 s after the lead reached the person: y ~= 2 s, the push 2 N/s * 2 s along
    assert m == pytest.approx(-(5.0 + 4.0), abs=1e-3)


def test_the_same_seed_draws_the_same_person() -> None:
    a, b = ListeningUser(), ListeningUser()
    a.reset(np.random.default_rng(7))
    b.reset(np.random.default_rng(7))
    assert (a.responder, a.p_comply, a.dead_time) == (b.responder, b.p_comply, b.dead_time)
    c = ListeningUser()
    c.reset(np.random.default_rng(8))
    assert (c.p_comply, c.dead_time) != (a.p_comply, a.dead_time)


# ------------------------------------------------------------------------------ the ear
def _timeline(voice: str) -> SpeechTimeline:
    phrases = [
        Phrase("go", "Go now.", None, ("keep",)),
        Phrase("keep", "Keep going.", None, ("done",)),
        Phrase("done", "Done.", None, ()),
    ]
    graph = PhraseGraph(
        phrases,
        "go",
        {"go": 1.0, "keep": 0.8, "done": 0.5},
        pause=0.5,
        voice=voice,
        intents={"go": "guide", "keep": "encourage"},
    )
    return SpeechTimeline(graph)


@pytest.mark.parametrize("voice", ["stretch", "natural"])
@pytest.mark.parametrize("a", [1.2, 1.0, 0.9, 0.7])
def test_the_ear_hears_each_last_word_as_the_voice_says_it(voice: str, a: float) -> None:
    sp = _timeline(voice)
    ear = Ear(sp)
    heard = []
    dt = 0.002
    while not sp.done:
        sp.step(dt, a)
        heard += ear.step(dt, a)
    assert [(v, i) for _, v, i in heard] == [("go", "guide"), ("keep", "encourage"), ("done", None)]
    starts = {u.phrase: u.t_start for u in sp.history}
    ends = {u.phrase: u.t_end for u in sp.history}
    for t, v, _ in heard:
        dur = sp.graph.duration[v]
        if voice == "natural" and v != "done":  # said at max(a, 0.9), then the voice waits
            expected = starts[v] + dur / max(a, SLOWEST)
            assert t == pytest.approx(expected, abs=dt)
        else:
            assert t == pytest.approx(ends[v], abs=1e-9)
        assert t <= ends[v] + 1e-9


# ------------------------------------------------------------------------------ in the env
def test_the_env_tells_a_listening_person_what_they_hear() -> None:
    env = gym.make(langenv.ENV_ID, users="listening", decision_hz=25, max_episode_steps=1500)
    env.reset(seed=4)
    base = env.unwrapped
    user = base.user
    assert isinstance(user, ListeningUser)
    assert not base.runs_compiled  # the person is not tabulated: Python ticks
    done = False
    while not done:
        _, _, terminated, truncated, _ = env.step(np.zeros(env.action_space.shape))
        done = terminated or truncated
    graph = base.graph
    said = [u for u in base.speech.utterances() if u.length is None]
    assert [i for _, i, _ in user.heard] == [graph.intent(u.phrase) for u in said]
    assert all(abs(t - u.t_end) < 0.5 and t <= u.t_end + 1e-9 for (t, _, _), u in
               zip(user.heard, said, strict=True))  # fmt: skip
    assert {"guide", "encourage"} <= {i for _, i, _ in user.heard}
    env.close()


def test_users_listening_is_refused_on_nothing_and_named_in_errors() -> None:
    with pytest.raises(ConfigError, match="'synthetic', 'listening', 'replay'"):
        gym.make(langenv.ENV_ID, users="hearing")


def test_a_batch_steps_a_listening_session_as_the_single_env_does() -> None:
    venv = gym.make_vec(langenv.ENV_ID, num_envs=2, users="listening")
    single = gym.make(langenv.ENV_ID, users="listening")
    obs, _ = venv.reset(seed=4)
    one, _ = single.reset(seed=4)
    zero = np.zeros(single.action_space.shape, np.float32)
    for _ in range(200):
        obs, *_ = venv.step(np.stack([zero, zero]))
        one, *_ = single.step(zero)
    assert np.array_equal(obs[0], one)
    heard = venv.unwrapped.envs[0].user.heard
    assert heard and heard == single.unwrapped.user.heard
    venv.close()
    single.close()
