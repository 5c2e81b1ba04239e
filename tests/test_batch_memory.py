"""A batch shares what never changes (issue 45): the sessions of a ``LangCtrlVectorEnv`` hold one
phrase graph, one clip library, one MuJoCo model, one ETC table and one calibrated person between
them, read-only; each keeps its own state (``MjData``, its person's drawn force); a graph holds
its clips' lengths, and stepping never loads audio. ``python -m bench.memory`` measures what a
session costs."""

from __future__ import annotations

import pickle
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

from langenv.batch import LangCtrlVectorEnv
from langenv.speech.audio import ClipLibrary
from langenv.speech.graph import PhraseGraph, graph_path
from langenv.speech.shared import shared_clips, shared_graph
from langenv.users import SyntheticUser


@pytest.fixture(scope="module")
def batch() -> Iterator[LangCtrlVectorEnv]:
    envs = LangCtrlVectorEnv(3, parallel="serial")
    envs.reset(seed=0)
    yield envs
    envs.close()


def test_sessions_share_what_never_changes(batch: LangCtrlVectorEnv) -> None:
    a, b, c = batch.envs
    for other in (b, c):
        assert other.graph is a.graph
        assert other.clips is a.clips is shared_clips()
        assert other.motion.arm.model is a.motion.arm.model
        assert other.motion.etc.tab is a.motion.etc.tab
        assert other.user.params is a.user.params
        assert other.user.grid is a.user.grid
    # ... and each keeps its own state
    assert len({id(e.motion.arm.data) for e in batch.envs}) == 3
    assert len({id(e.speech) for e in batch.envs}) == 3
    assert a.user.f_applied is not b.user.f_applied  # two people drawn


def test_shared_arrays_are_read_only(batch: LangCtrlVectorEnv) -> None:
    env = batch.envs[0]
    for arr in (env.user.grid, env.user.f_applied, env.motion.etc.tab, env.motion.etc.prm):
        assert not arr.flags.writeable
        with pytest.raises(ValueError):
            arr.flat[0] = 1.0
    with pytest.raises(TypeError):
        env.graph.duration[env.graph.start] = 1.0  # type: ignore[index]
    fresh = SyntheticUser()
    assert not fresh.f_applied.flags.writeable and not fresh.f_applied.any()


def test_stepping_a_batch_never_loads_audio(
    batch: LangCtrlVectorEnv, monkeypatch: pytest.MonkeyPatch
) -> None:
    def loads(*args: object, **kwargs: object) -> None:
        raise AssertionError("audio loaded while stepping")

    for name in ("clip", "load_file", "synthesize", "_read_file", "_spoken", "_read_cache"):
        monkeypatch.setattr(ClipLibrary, name, loads)
    batch.reset(seed=3)
    actions = np.zeros((batch.num_envs, *batch.single_action_space.shape))  # type: ignore[misc]
    for _ in range(60):  # past phrase boundaries (Python ticks) in every session
        batch.step(actions)
    again = LangCtrlVectorEnv(2, parallel="serial")  # a graph already loaded: no audio either
    again.close()


def test_a_graph_holds_its_clips_lengths_not_their_audio() -> None:
    """Loading a graph measures its clips without keeping them; rendering loads them, of the
    lengths measured."""
    measured = ClipLibrary()
    graph = PhraseGraph.load(graph_path("study"), measured)
    assert measured._memory == {}
    loaded = ClipLibrary()
    for phrase in graph.source_phrases.values():
        if not phrase.is_pause:
            clip = loaded.clip(phrase)
            assert clip.size == measured.samples(phrase)
            assert not clip.flags.writeable
    assert PhraseGraph.load(graph_path("study"), loaded).duration == graph.duration


def test_shared_graph_is_loaded_once_per_file_content(tmp_path: Path) -> None:
    path = tmp_path / "g.yaml"
    path.write_text(graph_path("study").read_text())
    first = shared_graph(path)
    assert shared_graph(path) is first
    assert shared_graph(path, ClipLibrary()) is not first  # another library: its own graph
    path.write_text(path.read_text() + "\n# edited\n")
    assert shared_graph(path) is not first


def test_a_person_pickles_without_its_view() -> None:
    user = SyntheticUser()
    user.reset(np.random.default_rng(4))
    back = pickle.loads(pickle.dumps(user))
    times = [0.0, 1.234, 7.5, 30.0, 119.99]
    assert [back.magnitude(t) for t in times] == [user.magnitude(t) for t in times]
    assert type(user.magnitude(1.234)) is float
