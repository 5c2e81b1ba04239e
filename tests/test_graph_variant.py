"""Randomised variants of a phrase graph (langenv.speech.variant) and env.use_phrase_graph."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from langenv.env import LangCtrlEnv
from langenv.errors import ConfigError
from langenv.speech.graph import PhraseGraph, graph_path
from langenv.speech.variant import GraphVariation, vary_graph

STUDY = PhraseGraph.load(graph_path("study"))
DEFAULT = PhraseGraph.load(graph_path("default"))


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), which=st.sampled_from(["study", "default"]))
def test_variant_keeps_the_number_of_choices_and_is_a_valid_graph(seed: int, which: str) -> None:
    graph = STUDY if which == "study" else DEFAULT
    v = vary_graph(graph, np.random.default_rng(seed), GraphVariation())
    assert v.max_children == graph.max_children
    assert v.start == graph.start
    added = {f"{u}~alt" for u in graph.phrases} | {f"{u}~alt#wait" for u in graph.phrases}
    assert set(v.phrases) <= set(graph.phrases) | added
    assert v.final_wait == graph.final_wait and set(v.repeats) <= set(graph.repeats)
    assert 0.0 < v.t_min(v.start) <= v.t_max(v.start)
    for u in v.pauses & set(graph.phrases):  # a wait added for an added wording has no twin
        lo, hi = v.phrases[u].bounds  # type: ignore[misc]
        glo, _ = graph.phrases[u].bounds  # type: ignore[misc]
        assert lo / glo == pytest.approx(v.pause / graph.pause) if glo > 0 else lo == 0.0
        assert hi <= 10.0


def test_rate_and_pause_scale_only() -> None:
    var = GraphVariation(p_drop=0.0, p_add=0.0, tts_rate=(1.25, 1.25), pause_scale=(2.0, 2.0))
    v = vary_graph(STUDY, np.random.default_rng(0), var)
    assert set(v.phrases) == set(STUDY.phrases)
    for u in STUDY.phrases:
        assert v.duration[u] == pytest.approx(STUDY.duration[u] / 1.25)
    assert v.pause == pytest.approx(2.0 * STUDY.pause)


def test_same_seed_same_variant_and_variants_differ() -> None:
    a = vary_graph(STUDY, np.random.default_rng(5), GraphVariation())
    b = vary_graph(STUDY, np.random.default_rng(5), GraphVariation())
    assert dict(a.duration) == dict(b.duration) and a._children == b._children
    others = {
        round(vary_graph(STUDY, np.random.default_rng(s), GraphVariation()).t_max(STUDY.start), 6)
        for s in range(8)
    }
    assert len(others) == 8


def test_drops_and_adds_happen() -> None:
    rng = np.random.default_rng(1)
    sizes = {len(vary_graph(STUDY, rng, GraphVariation(p_drop=0.3, p_add=0.3))) for _ in range(20)}
    assert min(sizes) < len(STUDY) < max(sizes)


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"p_drop": 1.0}, "p_drop"),
        ({"p_add": -0.1}, "p_add"),
        ({"tts_rate": (0.0, 1.0)}, "tts_rate"),
        ({"pause_scale": (2.0, 1.0)}, "pause_scale"),
        ({"tries": 0}, "tries"),
    ],
)
def test_bad_variation_is_named(kwargs: dict[str, object], match: str) -> None:
    with pytest.raises(ConfigError, match=match):
        GraphVariation(**kwargs)  # type: ignore[arg-type]


def test_env_speaks_a_variant_from_the_next_reset() -> None:
    env = LangCtrlEnv(phrase_graph="study")
    v = vary_graph(STUDY, np.random.default_rng(2), GraphVariation(tts_rate=(0.9, 0.9)))
    env.use_phrase_graph(v)
    obs, _ = env.reset(seed=0)
    assert env.graph is v and env.speech.graph is v
    assert obs[1] * 40.0 == pytest.approx(env.t_a, abs=1e-5)
    done = False
    while not done:
        _, _, term, trunc, info = env.step(np.zeros(3))
        done = term or trunc
    assert info["speech_done"] and set(env.speech.path) <= set(v.phrases)
    with pytest.raises(ConfigError, match="choices"):
        env.use_phrase_graph(DEFAULT)


def test_long_pauses_and_gaps_scaled_up_stay_within_the_longest_pause() -> None:
    """A pause or a repeat's gap whose minimum times the drawn scale passes 10 s (the longest
    pause) had its maximum clipped to 10 s but not its minimum: min > max, and vary_graph
    raised PhraseGraphError instead of returning a variant."""
    from langenv.speech.phrase import Phrase
    from langenv.speech.repeat import Repeat

    phrases = [
        Phrase("a", "Go.", None, ("p",)),
        Phrase("p", None, None, ("k", "t"), "pause", (8.0, 9.0)),
        Phrase("k", "Keep going.", None, ("t",)),
        Phrase("t", "Done.", None, ()),
    ]
    g = PhraseGraph(
        phrases,
        "a",
        {"a": 1.0, "k": 1.0, "t": 0.5},
        repeats=[Repeat("r", ("k",), 3, (8.0, 9.0))],
        final_wait=True,
    )
    v = vary_graph(g, np.random.default_rng(0), GraphVariation(pause_scale=(1.3, 1.5)))
    assert v.slot_range("p") == (10.0, 10.0)
    assert v.repeats["r"].gap == (10.0, 10.0)
