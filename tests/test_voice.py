"""The natural voice: clips said at max(a, 0.9), then a wait until the timeline reaches their
end."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from eval.episode import EpisodeLog, Utterance
from eval.metrics import content_time, episode_metrics, voice_trace
from langenv.errors import ConfigError, PhraseGraphError, ScriptError
from langenv.speech.audio import ClipLibrary
from langenv.speech.author import author, parse_script
from langenv.speech.graph import PhraseGraph
from langenv.speech.phrase import Phrase
from langenv.speech.render import render_history
from langenv.speech.variant import GraphVariation, vary_graph
from langenv.speech.voice import SLOWEST, NaturalVoice, check_voice, voice_rate


def two_clips(clips: ClipLibrary, voice: str) -> PhraseGraph:
    phrases = [
        Phrase("a", "I want you to move your hand away from your body.", None, ("b",)),
        Phrase("b", "And you're done.", None, ()),
    ]
    dur = {p.id: clips.duration(p) for p in phrases}
    return PhraseGraph(phrases, "a", dur, pause=0.3, voice=voice)


def sound_runs(y: np.ndarray, sr: int, gap: float = 0.15) -> list[tuple[float, float]]:
    """(start, end) in s of the stretches of sound separated by silences longer than ``gap``."""
    loud = np.flatnonzero(np.abs(y) > 1e-3)
    runs = [[loud[0], loud[0]]]
    for k in loud[1:]:
        if k - runs[-1][1] > gap * sr:
            runs.append([k, k])
        runs[-1][1] = k
    return [(s / sr, e / sr) for s, e in runs]


def test_at_a_slow_pace_the_natural_voice_says_the_clip_at_its_rate_then_waits(
    clips: ClipLibrary,
) -> None:
    a_slow = 0.6
    t = np.linspace(0.0, 12.0, 601)
    a = np.full_like(t, a_slow)
    sr = clips.sr
    stretched = render_history(two_clips(clips, "stretch"), clips, ["a", "b"], t, a)
    natural = render_history(two_clips(clips, "natural"), clips, ["a", "b"], t, a)
    length_a = two_clips(clips, "natural").duration["a"]
    slot_end = length_a / a_slow  # where the timeline leaves the first clip
    first_n = sound_runs(natural, sr)[0]
    first_s = [r for r in sound_runs(stretched, sr) if r[0] < slot_end][-1]
    # the first clip: said in about its own length (at least 0.9 of its natural rate), not
    # stretched to 1/0.6 of it
    assert first_n[1] - first_n[0] < 1.05 * length_a / SLOWEST
    assert first_s[1] - first_n[0] > 1.4 * length_a
    # ...and then silence until the slot ends: the second clip starts where the stretched one does
    second_n = next(r for r in sound_runs(natural, sr) if r[0] > first_n[1] + 0.2)
    second_s = next(r for r in sound_runs(stretched, sr) if r[0] > slot_end)
    assert second_n[0] == pytest.approx(second_s[0], abs=0.03)
    # the last clip follows the pace: both voices end together
    assert sound_runs(natural, sr)[-1][1] == pytest.approx(
        sound_runs(stretched, sr)[-1][1], abs=0.03
    )


def test_at_paces_of_one_or_more_the_natural_voice_is_the_stretched_one(clips: ClipLibrary) -> None:
    t = np.linspace(0.0, 8.0, 401)
    a = 1.0 + 0.3 * (t / 8.0)
    stretched = render_history(two_clips(clips, "stretch"), clips, ["a", "b"], t, a)
    natural = render_history(two_clips(clips, "natural"), clips, ["a", "b"], t, a)
    assert natural.shape == stretched.shape
    np.testing.assert_allclose(natural, stretched, atol=1e-5)


@settings(max_examples=60, deadline=None)
@given(
    paces=st.lists(st.floats(0.6, 1.4), min_size=8, max_size=60),
    start=st.floats(0.0, 0.3),
    width=st.floats(0.2, 0.7),
)
def test_voice_rate_says_exactly_what_the_speech_covers(
    paces: list[float], start: float, width: float
) -> None:
    n = len(paces)
    t = np.arange(n) * 0.05
    a = np.asarray(paces)
    t0 = start * t[-1]
    t1 = t0 + width * t[-1]
    v, waiting = voice_rate(t, a, [(t0, t1)])
    ends = np.append(t[1:], t[-1] + 0.05)
    inside = (ends > t0) & (t < t1)  # the samples whose interval [t_i, t_i+1) meets the clip's
    np.testing.assert_array_equal(v[~inside], a[~inside])  # outside the clip: the pace itself
    speaking = inside & ~waiting
    assert np.all(v[speaking] >= np.maximum(a[speaking], SLOWEST) - 1e-12)  # never slower
    assert np.all(v[waiting] == 1.0) and not waiting[~inside].any()
    w = np.clip(np.minimum(ends, t1) - np.maximum(t, t0), 0.0, None)
    covered, said = float(np.sum(a * w)), float(np.sum((v * w)[speaking]))
    # the voice says what the timeline covers, to within the sample it finishes in
    assert said >= covered - 1e-9
    assert said <= covered + 1.4 * 0.05 + 1e-9
    # once waiting, it waits until the clip's slot ends
    if waiting.any():
        first = int(np.flatnonzero(waiting)[0])
        assert waiting[first : int(np.flatnonzero(inside)[-1]) + 1].all()


def test_voice_rate_and_natural_voice_reject_bad_input() -> None:
    with pytest.raises(ConfigError, match="same shape"):
        voice_rate(np.zeros(3), np.ones(4), [])
    with pytest.raises(ConfigError, match="sr must be"):
        NaturalVoice(0)
    voice = NaturalVoice(100)
    voice.clip(0.0, 1.0)
    with pytest.raises(ConfigError, match="in order"):
        voice.clip(0.5, 2.0)
    with pytest.raises(ConfigError, match="voice must be one of"):
        check_voice("robotic", "test")


def log_of(voice: str, a_slow: float = 0.6) -> EpisodeLog:
    t = np.arange(0.0, 6.0, 0.02)
    n = t.size
    a = np.full(n, a_slow)
    done = t >= 5.0
    utt = (Utterance("a", "A", 0.0, 2.5), Utterance("b", "B", 2.9, 5.0))
    return EpisodeLog(
        policy="lc",
        user="u",
        t=t,
        cooperation=np.full(n, 0.9),
        hand_speed=np.zeros(n),
        p=np.ones(n),
        a=a,
        t_x=np.zeros(n),
        t_a=np.zeros(n),
        em=np.zeros(n),
        motion_done=done,
        speech_done=done,
        utterances=utt,
        t_motion=5.0,
        t_speech=5.0,
        ret=0.0,
        voice=voice,
    )


def test_metrics_hear_the_natural_voice_and_count_its_waits_as_pauses(tmp_path: Path) -> None:
    stretched, natural = episode_metrics(log_of("stretch")), episode_metrics(log_of("natural"))
    assert stretched["voice_natural"] == stretched["a_within_0_1"] == 0.0
    # clip 'a' (2.5 s slot at a = 0.6: 1.5 s of words) is said at 0.9 in 1.5 / 0.9 s, then the
    # rest of the slot is a wait; the gap (0.4 s) and the last clip (2.1 s) follow a = 0.6
    wait = 2.5 - 1.5 / SLOWEST
    assert natural["voice_natural"] == pytest.approx(2.5 / 5.0, abs=0.01)
    assert natural["a_within_0_1"] == 0.0  # the speech pace itself is the same
    assert stretched["pause_share"] == pytest.approx(0.4 / 5.0, abs=0.01)
    assert natural["pause_share"] == pytest.approx((0.4 + wait) / 5.0, abs=0.01)
    _v, waiting = voice_trace(log_of("natural"))
    assert waiting.sum() * 0.02 == pytest.approx(wait, abs=0.03)
    # content heard over the motion (5 s): the stretched voice's words fill both clips' spans;
    # the natural voice says 'a' in 1.5 / 0.9 s and waits, so its wait is not content
    assert stretched["content_share"] == pytest.approx((2.5 + 2.1) / 5.0, abs=0.01)
    assert natural["content_share"] == pytest.approx((1.5 / SLOWEST + 2.1) / 5.0, abs=0.01)
    assert content_time(log_of("natural"), waiting, 2.0) == pytest.approx(1.5 / SLOWEST, abs=0.02)
    path = log_of("natural").save_npz(tmp_path / "log.npz")
    assert EpisodeLog.load_npz(path).voice == "natural"
    with pytest.raises(ConfigError, match="voice"):
        log_of("robotic")


def test_the_graph_and_its_variants_carry_the_voice(tmp_path: Path, clips: ClipLibrary) -> None:
    g = two_clips(clips, "natural")
    assert g.voice == "natural"
    varied = vary_graph(g, np.random.default_rng(0), GraphVariation(p_add=0.0, p_drop=0.0))
    assert varied.voice == "natural"
    with pytest.raises(PhraseGraphError, match="voice must be one of"):
        PhraseGraph([Phrase("a", "A", None, ())], "a", {"a": 1.0}, voice="robotic")
    assert PhraseGraph.load("langenv/assets/graphs/study.yaml").voice == "stretch"
    assert PhraseGraph.load("langenv/assets/graphs/default.yaml").voice == "natural"


def test_scripts_choose_their_voice_with_a_directive(tmp_path: Path, clips: ClipLibrary) -> None:
    script = tmp_path / "s.txt"
    script.write_text("@voice natural\nGo on.\nAnd you're done.\n")
    graph = author(script, tmp_path / "s.yaml", clips)
    assert graph.voice == "natural"
    assert "voice: natural" in (tmp_path / "s.yaml").read_text()
    assert parse_script("Go on.\n").voice == "stretch"
    assert "voice" not in (tmp_path / "s.yaml").read_text().split("phrases:")[1]
    bad = {
        "@voice robotic\nGo.\n": "s.txt:1:1: @voice takes one of stretch, natural",
        "Go.\n@voice natural\nDone.\n": "s.txt:2:1: @voice must come before the first step",
        "@voice\nGo.\n": "s.txt:1:1: @voice takes one of",
    }
    for text, message in bad.items():
        script.write_text(text)
        with pytest.raises(ScriptError) as info:
            author(script, tmp_path / "bad.yaml", clips)
        assert message in str(info.value)
        assert not (tmp_path / "bad.yaml").exists()


def three_clips(clips: ClipLibrary, pause: float, voice: str = "natural") -> PhraseGraph:
    phrases = [
        Phrase("a", "I want you to move your hand away from your body.", None, ("b",)),
        Phrase("b", "Keep going, slowly now.", None, ("c",)),
        Phrase("c", "And you're done.", None, ()),
    ]
    dur = {p.id: clips.duration(p) for p in phrases}
    return PhraseGraph(phrases, "a", dur, pause=pause, voice=voice)


def live_and_offline(
    graph: PhraseGraph, clips: ClipLibrary, until: float = 60.0
) -> tuple[np.ndarray, np.ndarray, int]:
    """A session at a slow, varying pace streamed live (ended at ``until`` s or 0.5 s after its
    speech), the offline rendering of its trace, and the blocks the stream starved."""
    from langenv.live.stream import BLOCK, SpeechStream
    from langenv.speech.timeline import SpeechTimeline

    timeline, stream = SpeechTimeline(graph), SpeechStream(graph, clips)
    t, dt, trace, live = 0.0, 0.002, [], []
    while t < until and (not timeline.done or t < timeline.t + 0.5):
        pace = 0.7 + 0.1 * np.sin(t)
        stream.record(t, pace, timeline.path, timeline.done, timeline.pause_lengths)
        trace.append((t, pace))
        live.append(stream.render(t, 4 * BLOCK))
        if not timeline.done:
            timeline.step(dt, pace)
        t += dt
    tt, aa = np.asarray(trace).T
    path, lengths = timeline.path, timeline.pause_lengths
    offline = render_history(graph, clips, path, tt, aa, pause_lengths=lengths)
    return np.concatenate(live), offline, stream.starved


def test_a_live_stream_of_a_natural_voice_with_short_pauses_never_starves(
    clips: ClipLibrary,
) -> None:
    """With little silence after a clip the content after it is not chosen yet when the voice,
    ahead of a slow speech, reaches the clip's end: the voice must wait before the vocoder
    needs it, so the live stream never starves and still equals the offline rendering."""
    for pause in (0.0, 0.05, 0.1):
        heard, offline, starved = live_and_offline(three_clips(clips, pause), clips)
        assert starved == 0, pause
        np.testing.assert_array_equal(heard, offline[: heard.size])


def test_a_session_cut_short_while_the_voice_waits_renders_as_it_streamed(
    clips: ClipLibrary,
) -> None:
    """Cut during the first clip's slot after its words were said: the offline rendering of the
    cut history ends the clip as the live stream did (with the silence after it, where the
    vocoder's last frames of the clip sound), not with the vocoder cut at the content's end."""
    for voice in ("natural", "stretch"):
        heard, offline, starved = live_and_offline(three_clips(clips, 0.4, voice), clips, 3.2)
        assert starved == 0
        np.testing.assert_array_equal(heard, offline[: heard.size])


class _Content:
    """A stand-in vocoder for :class:`NaturalVoice`: content is counted, not sounded (output 1.0
    where content is read); records each pull with where the speech was."""

    n_fft, hop = 64, 16

    def __init__(self, sr: int, seconds: float, voice: NaturalVoice) -> None:
        self.sr, self.tau, self.end, self.voice = sr, 0.0, seconds * sr, voice
        self.pulls: list[tuple[float, float, float, float]] = []  # (from, to, pace, speech)

    @property
    def content_time(self) -> float:
        return self.tau / self.sr

    @property
    def done(self) -> bool:
        return self.tau >= self.end - 1e-9

    def pull(self, n: int, pace: float) -> np.ndarray:
        k = min(n, int(np.ceil((self.end - self.tau) / pace - 1e-9)))
        lo, hi = self.tau / self.sr, (self.tau + pace * k) / self.sr
        self.pulls.append((lo, hi, pace, self.voice.speech_pos))
        self.tau += pace * k
        return np.ones(k, np.float32)


@settings(max_examples=80, deadline=None)
@given(
    words=st.lists(st.floats(0.01, 1.0), min_size=1, max_size=5),
    gaps=st.lists(st.floats(0.0, 0.4), min_size=5, max_size=5),
    paces=st.lists(st.floats(0.3, 2.0), min_size=4, max_size=40),
)
def test_the_natural_voice_says_each_clip_at_its_rate_or_faster_and_keeps_with_the_speech(
    words: list[float], gaps: list[float], paces: list[float]
) -> None:
    sr, n = 1000, 25
    voice = NaturalVoice(sr)
    spans, pos = [], 0.0  # (start, end of the words, end of the silence after them)
    for w, g in zip(words, gaps, strict=False):
        voice.clip(pos, pos + w, g)
        spans.append((pos, pos + w, pos + w + g))
        pos += w + g
    voc = _Content(sr, pos + 0.5, voice)  # a last clip of 0.5 s follows the pace
    # pieces end on whole output samples: voice and speech may part by a sample's worth a wait
    slack = (len(spans) + 1) * max(*paces, 1.0) / sr
    blocks = 0
    while not voc.done and blocks < 10_000:
        a = paces[blocks % len(paces)]
        before = (voc.content_time, voice.speech_pos)
        y, starved = voice.block(voc, n, a)
        blocks += 1
        assert not starved
        assert y.size == n or voc.done  # a block is whole until the content ends
        # the voice is never behind the speech, and ahead of it only inside a clip's slot
        assert voc.content_time >= voice.speech_pos - slack
        if voc.content_time > voice.speech_pos + slack:
            assert any(s - 1e-9 <= voice.speech_pos <= k + 1e-9 for s, _, k in spans)
        # silence is heard only while the voice waits for the speech
        if np.any(y == 0.0):
            assert before[0] >= before[1] - slack
    assert voc.done
    for lo, hi, pace, speech in voc.pulls:
        for s, e, k in spans:
            reach = (pace + 1.0) * (_Content.n_fft / 2 + _Content.hop) / sr
            if s - 1e-9 <= lo and hi <= min(e, k - 3.0 * 0.096) - 1e-9:
                assert pace >= SLOWEST  # the words of a clip with a successor: not dragged
            if s - 1e-9 <= speech < k and lo > speech + slack:
                # ahead of the speech, the voice never reads past the silence after the clip:
                # the content after it is chosen only when the speech gets there
                assert hi + reach <= k + pace / sr + 1e-6


def test_a_replay_is_voiced_as_its_session_was(clips: ClipLibrary) -> None:
    """A log says how its speech was voiced: a video re-renders it so, whatever the graph's YAML
    says today (logs of langctrl 0.5 and before were stretched; ``default`` is natural now)."""
    from eval.video import session_audio
    from langenv.speech.graph import graph_path
    from langenv.speech.render import plan_speech

    graph = PhraseGraph.load(graph_path("default"), clips=clips)
    assert graph.voice == "natural" and graph.with_voice("natural") is graph
    stretched = graph.with_voice("stretch")
    assert stretched.voice == "stretch" and stretched.t_min(graph.start) == graph.t_min(graph.start)
    with pytest.raises(PhraseGraphError, match="voice must be one of"):
        graph.with_voice("robotic")
    t = np.arange(0.0, 16.0, 0.02)
    a = np.full(t.size, 0.7)
    said = plan_speech(graph, t, a)
    utterances = tuple(Utterance(u.phrase, "", u.t_start, u.t_end, u.length) for u in said)
    log = dataclasses.replace(log_of("stretch", 0.7), utterances=utterances, phrase_graph="default")
    audio, _sr = session_audio(log, clips=clips)
    np.testing.assert_array_equal(audio, render_history(stretched, clips, said, log.t, log.a))
    natural, _sr = session_audio(dataclasses.replace(log, voice="natural"), clips=clips)
    np.testing.assert_array_equal(natural, render_history(graph, clips, said, log.t, log.a))
    assert not np.array_equal(audio, natural)


def test_a_fillers_wait_counts_as_silence_not_as_the_filler_said() -> None:
    """Clip 'a', filler 'f' and the last clip 'b' at a = 0.6: the natural voice says the filler's
    0.7 s slot (0.42 s of content) in 0.42 / 0.9 s and waits the rest; that wait is silence, so the
    shares (silence, fillers, the rest said) still add up to the speech time."""
    utt = (
        Utterance("a", "A", 0.0, 2.5),
        Utterance("f", "okay", 2.9, 3.6, filler=True),
        Utterance("b", "B", 4.0, 5.0),
    )
    stretched = episode_metrics(dataclasses.replace(log_of("stretch"), utterances=utt))
    natural = episode_metrics(dataclasses.replace(log_of("natural"), utterances=utt))
    assert stretched["filler_share"] == pytest.approx(0.7 / 5.0, abs=0.01)
    said_f = 0.42 / SLOWEST
    assert natural["filler_share"] == pytest.approx(said_f / 5.0, abs=0.01)
    # waits: 2.5 - 1.5 / 0.9 s in 'a' and 0.7 - 0.42 / 0.9 s in 'f'; gaps 0.8 s
    waits = (2.5 - 1.5 / SLOWEST) + (0.7 - said_f)
    assert natural["pause_share"] == pytest.approx((waits + 0.8) / 5.0, abs=0.01)
