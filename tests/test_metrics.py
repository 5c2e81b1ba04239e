"""Episode logs (validation, .npz round trip, recorder) and the per-session metrics."""

from __future__ import annotations

import math
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from eval.episode import EpisodeLog, EpisodeRecorder, Utterance
from eval.metrics import (
    METRIC_COLUMNS,
    episode_metrics,
    time_mean,
    time_samples,
    time_weights,
    window_mask,
)
from langenv.errors import ConfigError, SessionDataError


def hand_log(**overrides: object) -> EpisodeLog:
    """10 samples at 1 Hz; motion over from t = 6 s, speech over from t = 8 s."""
    t = np.arange(10.0)
    fields: dict[str, object] = {
        "policy": "lc",
        "user": "u1",
        "t": t,
        "cooperation": np.array([1, 1, 0.5, 0.5, 1, 1, 1, 1, 1, 1], dtype=float),
        "hand_speed": np.full(10, 0.1),
        "p": np.array([1, 1.2, 1.2, 0.8, 0.8, 1, 9, 9, 9, 9], dtype=float),  # 9: after motion
        "a": np.array(
            [1, 1.05, 1.1, 0.7, 0.7, 0.9, 1.3, 1.0, 5, 5], dtype=float
        ),  # 5: after speech
        "t_x": np.maximum(6.0 - t, 0.0),
        "t_a": np.maximum(8.0 - t, 0.0),
        "em": np.array([2, 2, 2, -1, -1, 3, 2, 1, 7, 7], dtype=float),  # 7: after both
        "motion_done": t >= 6.0,
        "speech_done": t >= 8.0,
        "utterances": (Utterance("intro", "hello", 0.0, 3.0), Utterance("done", "bye", 3.5, 8.0)),
        "t_motion": 6.0,
        "t_speech": 8.0,
        "ret": -3.5,
    }
    fields.update(overrides)
    return EpisodeLog(**fields)  # type: ignore[arg-type]


def smooth_log(hz: float, t_motion: float = 9.0, t_speech: float = 10.0) -> EpisodeLog:
    """A smooth session sampled at ``hz``: the same underlying signals at any rate."""
    t = np.arange(0.0, max(t_motion, t_speech) + 0.5, 1.0 / hz)
    c = 1.0 - 0.5 * np.exp(-((t - 4.0) ** 2))
    a = 1.0 - 0.3 * np.sin(0.7 * t) ** 2
    p = 1.0 + 0.2 * np.sin(0.5 * t)
    t_x, t_a = np.maximum(t_motion - t, 0.0), np.maximum(t_speech - t, 0.0)
    return EpisodeLog(
        "lc",
        "smooth",
        t,
        c,
        0.1 * c,
        p,
        a,
        t_x,
        t_a,
        t_a - t_x,
        t >= t_motion,
        t >= t_speech,
        (),
        t_motion,
        t_speech,
        0.0,
    )


# ------------------------------------------------------------------ EpisodeLog / Utterance


def test_log_is_read_only_and_knows_am() -> None:
    log = hand_log()
    assert log.n == 10 and log.am == pytest.approx(2.0)
    with pytest.raises(ValueError):
        log.p[0] = 3.0
    assert log.motion_done.dtype == np.bool_


@pytest.mark.parametrize(
    ("overrides", "field"),
    [
        ({"p": np.ones(9)}, "p"),
        ({"a": np.r_[np.ones(9), np.nan]}, "a"),
        ({"em": np.r_[np.ones(9), np.inf]}, "em"),
        ({"t": np.array([0, 1, 2, 2, 4, 5, 6, 7, 8, 9.0])}, "t"),
        ({"hand_speed": -np.ones(10)}, "hand_speed"),
        ({"motion_done": np.array([0, 0, 0, 0, 0, 0, 1, 0, 1, 1], dtype=bool)}, "motion_done"),
        ({"speech_done": np.zeros(8, dtype=bool)}, "speech_done"),
        ({"t_motion": math.nan}, "t_motion"),
        ({"t_speech": -1.0}, "t_speech"),
        ({"ret": math.inf}, "ret"),
        ({"policy": ""}, "policy"),
        (
            {"utterances": (Utterance("b", "", 2.0, 3.0), Utterance("a", "", 1.0, 2.0))},
            "utterances",
        ),
    ],
)
def test_log_validation_names_the_field(overrides: dict[str, object], field: str) -> None:
    with pytest.raises(ValueError, match=field) as info:
        hand_log(**overrides)
    assert isinstance(info.value, ConfigError)


def test_log_needs_two_samples() -> None:
    z, done = np.zeros(1), np.ones(1, dtype=bool)
    with pytest.raises(ConfigError, match="at least 2"):
        EpisodeLog("lc", "u", z, z, z, z, z, z, z, z, done, done, (), 0.0, 0.0, 0.0)


def test_utterance_validation() -> None:
    with pytest.raises(ConfigError, match="t_end"):
        Utterance("x", "text", 2.0, 1.0)
    with pytest.raises(ConfigError, match="phrase"):
        Utterance("", "text", 0.0, 1.0)
    with pytest.raises(ConfigError, match="t_start"):
        Utterance("x", "text", math.nan, 1.0)
    assert Utterance("x", "", 1.0, 2.5).duration == pytest.approx(1.5)


@pytest.mark.parametrize("utterances", [(), (Utterance("intro", "héllo, «quoted»", 0.5, 2.0),)])
def test_npz_round_trip(tmp_path: Path, utterances: tuple[Utterance, ...]) -> None:
    log = hand_log(utterances=utterances)
    path = log.save_npz(tmp_path / "ep.npz")
    back = EpisodeLog.load_npz(path)
    assert (back.policy, back.user, back.utterances) == (log.policy, log.user, utterances)
    assert (back.t_motion, back.t_speech, back.ret) == (log.t_motion, log.t_speech, log.ret)
    for name in ("t", "cooperation", "hand_speed", "p", "a", "t_x", "t_a", "em"):
        np.testing.assert_array_equal(getattr(back, name), getattr(log, name))
    np.testing.assert_array_equal(back.speech_done, log.speech_done)
    assert [p.name for p in tmp_path.iterdir()] == ["ep.npz"]  # no temp file left


def test_load_npz_errors_name_the_file(tmp_path: Path) -> None:
    bad = tmp_path / "bad.npz"
    bad.write_bytes(b"not a zip")
    with pytest.raises(SessionDataError, match=r"bad\.npz"):
        EpisodeLog.load_npz(bad)
    other = tmp_path / "other.npz"
    np.savez(other, x=np.zeros(3))
    with pytest.raises(SessionDataError, match=r"other\.npz"):
        EpisodeLog.load_npz(other)


def test_recorder_builds_utterances_from_phrase_runs() -> None:
    rec = EpisodeRecorder("lc", "u7")
    # the env reports the phrase also during the pause after it; in_pause tells them apart
    phrases = ["intro", "intro", "intro", "slide", "slide", "slide", None, None]
    pause = [False, False, True, False, False, True, False, False]
    for k, ph in enumerate(phrases):
        rec.append(
            {
                "time": 0.5 * k,
                "cooperation": 1.0,
                "hand_speed": 0.1,
                "p": 1.0,
                "a": 1.0,
                "t_x": 3.0 - 0.5 * k,
                "t_a": 3.0 - 0.5 * k,
                "em": 0.0,
                "motion_done": k >= 6,
                "speech_done": k >= 6,
                "phrase": ph,
                "in_pause": pause[k],
            }
        )
    log = rec.build(ret=-1.0, texts={"intro": "hello"})
    assert log.utterances == (
        Utterance("intro", "hello", 0.0, 1.0),
        Utterance("slide", "", 1.5, 2.5),
    )
    assert log.t_motion == 3.0 and log.t_speech == 3.0 and log.n == len(phrases)
    with pytest.raises(ConfigError, match="cooperation"):
        rec.append({"time": 9.0})


def test_recorder_takes_exact_utterances_and_skips_unknown_end_times() -> None:
    rec = EpisodeRecorder("lc-noap", "u2")
    for k in range(5):
        rec.append(
            {
                "t": 0.04 * k,
                "cooperation": 1.0,
                "hand_speed": 0.0,
                "p": 1.0,
                "a": 1.0,
                "t_x": 0.0,
                "t_a": 0.0,
                "em": 0.0,
                "motion_done": k >= 2,
                "speech_done": k >= 3,
                "t_motion": math.nan,
                "t_speech": None,
            }
        )
    said = [SimpleNamespace(phrase="intro", t_start=np.float32(0.0), t_end=0.11)]
    log = rec.build(0.0, utterances=said, texts={"intro": "hi"}, t_speech=0.115)
    assert log.utterances == (Utterance("intro", "hi", 0.0, 0.11),)
    assert log.t_motion == pytest.approx(0.08) and log.t_speech == 0.115
    with pytest.raises(ConfigError, match="2 samples"):
        EpisodeRecorder("lc", "u").build(0.0)


def test_recorder_names_a_missing_key_and_keeps_its_samples() -> None:
    info = {
        "time": 0.0, "cooperation": 1.0, "hand_speed": 0.0, "p": 1.0, "a": 1.0, "t_x": 5.0,
        "t_a": 5.0, "em": 0.0, "motion_done": False, "speech_done": False,
    }  # fmt: skip
    rec = EpisodeRecorder("lc", "u")
    rec.append(info)
    for key in ("time", "em", "speech_done"):
        with pytest.raises(ConfigError, match=repr(key)):
            rec.append({k: v for k, v in info.items() if k != key})
    rec.append({**info, "t": 0.5, "time": 9.0})  # "t" wins over "time"
    assert len(rec) == 2
    log = rec.build(0.0, t_motion=1.0, t_speech=1.0)
    assert log.t.tolist() == [0.0, 0.5] and log.p.tolist() == [1.0, 1.0]


def test_recorder_copies_the_scene_arrays_it_is_given() -> None:
    """The scene keys may be live views of the simulation (``eval.compare`` passes MuJoCo's
    ``qpos``): each sample keeps the values of its own step."""
    qpos, force = np.zeros(6), np.zeros(3)
    rec = EpisodeRecorder("lc", "u")
    for k in range(3):
        qpos[:] = k
        force[:] = -k
        rec.append(
            {
                "time": 0.1 * k, "cooperation": 1.0, "hand_speed": 0.0, "p": 1.0, "a": 1.0,
                "t_x": 1.0, "t_a": 1.0, "em": 0.0, "motion_done": False, "speech_done": False,
                "qpos": qpos, "f_user": force,
            }
        )  # fmt: skip
    log = rec.build(0.0, t_motion=1.0, t_speech=1.0)
    assert log.qpos is not None and log.f_user is not None
    assert log.qpos.dtype == np.float32 and log.qpos[:, 0].tolist() == [0.0, 1.0, 2.0]
    assert log.f_user[:, 2].tolist() == [0.0, -1.0, -2.0]


def test_recorder_extend_is_append_per_sample_and_checks_before_keeping() -> None:
    info = {
        "time": np.array([0.0, 0.1]), "cooperation": np.ones(2), "hand_speed": np.zeros(2),
        "p": np.ones(2), "a": np.ones(2), "t_x": np.array([2.0, 1.9]), "t_a": np.array([2.0, 2.0]),
        "em": np.array([0.0, 0.1]), "motion_done": np.zeros(2), "speech_done": np.zeros(2),
        "qpos": np.zeros((2, 6)), "f_user": np.zeros((2, 3)),
    }  # fmt: skip
    one = EpisodeRecorder("lc", "u")
    for k in range(2):
        one.append({**{key: v[k] for key, v in info.items()}, "phrase": "intro", "t_motion": 5.0})
    many = EpisodeRecorder("lc", "u")
    many.append({**{key: v[0] for key, v in info.items()}, "phrase": "intro", "t_motion": 5.0})
    with pytest.raises(ConfigError, match="qpos"):
        many.extend({**info, "qpos": np.zeros((1, 6))}, "intro")
    with pytest.raises(ConfigError, match="'em'"):
        many.extend({k: v for k, v in info.items() if k != "em"}, "intro")
    assert len(many) == 1  # nothing kept of the refused samples
    many.extend({k: v[1:] for k, v in info.items()}, "intro")
    a, b = one.build(0.0, t_speech=5.0), many.build(0.0, t_speech=5.0)
    assert a.t_motion == b.t_motion == 5.0  # the appended t_motion is kept after extend
    assert a.utterances == b.utterances and np.array_equal(a.qpos, b.qpos)  # type: ignore[arg-type]
    assert all(np.array_equal(getattr(a, n), getattr(b, n)) for n in ("t", "t_x", "em", "p"))


# ------------------------------------------------------------------ metrics


def test_metrics_on_hand_built_log() -> None:
    m = episode_metrics(hand_log())
    assert tuple(m) == METRIC_COLUMNS
    assert (m["policy"], m["user"]) == ("lc", "u1")
    assert m["am"] == pytest.approx(2.0) and m["abs_am"] == pytest.approx(2.0)
    # speech window: samples 0..7 (uniform weights)
    a = np.array([1, 1.05, 1.1, 0.7, 0.7, 0.9, 1.3, 1.0])
    assert m["a_mean"] == pytest.approx(a.mean())
    assert m["a_dev"] == pytest.approx(np.abs(a - 1).mean())
    assert m["a_within_0_1"] == pytest.approx(5 / 8)  # 1, 1.05, 1.1 (boundary), 0.9, 1.0
    # motion window: samples 0..5
    assert m["p_mean"] == pytest.approx(np.mean([1, 1.2, 1.2, 0.8, 0.8, 1]))
    assert m["coop_mean"] == pytest.approx(np.mean([1, 1, 0.5, 0.5, 1, 1]))
    # either window: samples 0..7
    assert m["em_mean_abs"] == pytest.approx(np.mean([2, 2, 2, 1, 1, 3, 2, 1]))
    assert (m["t_motion"], m["t_speech"], m["return"]) == (6.0, 8.0, -3.5)


def test_am_is_negative_when_speech_ends_first() -> None:
    t = np.arange(10.0)
    log = hand_log(t_speech=4.0, speech_done=t >= 4.0)
    m = episode_metrics(log)
    assert m["am"] == pytest.approx(-2.0) and m["abs_am"] == pytest.approx(2.0)
    assert m["a_mean"] == pytest.approx(np.mean([1, 1.05, 1.1, 0.7]))


def test_empty_window_gives_nan() -> None:
    log = hand_log(speech_done=np.ones(10, dtype=bool), t_speech=0.0)
    m = episode_metrics(log)
    assert math.isnan(float(m["a_mean"])) and math.isnan(float(m["a_within_0_1"]))
    assert math.isfinite(float(m["p_mean"]))


def test_time_weighting_with_uneven_spacing() -> None:
    t = np.array([0.0, 1.0, 3.0, 4.0])
    np.testing.assert_allclose(time_weights(t), [1.0, 2.0, 1.0, 1.0])
    assert time_mean(np.array([1.0, 2.0, 3.0, 4.0]), t) == pytest.approx(12.0 / 5.0)
    mask = np.array([True, True, False, False])
    assert time_mean(np.array([1.0, 2.0, 3.0, 4.0]), t, mask) == pytest.approx(5.0 / 3.0)
    with pytest.raises(ConfigError, match="mask"):
        time_mean(np.ones(4), t, np.ones(3, dtype=bool))
    with pytest.raises(ConfigError, match="increasing"):
        time_weights(np.array([0.0, 0.0, 1.0]))


def test_metrics_do_not_depend_on_log_rate() -> None:
    slow, fast = episode_metrics(smooth_log(25.0)), episode_metrics(smooth_log(500.0))
    for key in ("a_mean", "a_dev", "p_mean", "coop_mean", "em_mean_abs"):
        assert slow[key] == pytest.approx(fast[key], abs=0.01), key
    assert slow["a_within_0_1"] == pytest.approx(fast["a_within_0_1"], abs=0.02)


def test_time_samples_pool_equally_at_any_rate() -> None:
    slow, fast = smooth_log(25.0), smooth_log(500.0)
    for window in ("motion", "speech", "either", "all"):
        a, b = time_samples(slow, "a", window), time_samples(fast, "a", window)
        assert abs(a.size - b.size) <= 2, window
        assert a.size == pytest.approx(50.0 * window_mask(fast, window).sum() / 500.0, abs=2)
    assert np.median(time_samples(slow, "a", "speech")) == pytest.approx(
        np.median(time_samples(fast, "a", "speech")), abs=0.01
    )
    with pytest.raises(ConfigError, match="name"):
        time_samples(slow, "speech_done", "all")
    with pytest.raises(ConfigError, match="window"):
        window_mask(slow, "later")  # type: ignore[arg-type]


finite = st.floats(min_value=-1e3, max_value=1e3, allow_nan=False)


@settings(max_examples=60, deadline=None)
@given(
    x=st.lists(finite, min_size=2, max_size=30),
    gaps=st.lists(st.floats(min_value=1e-3, max_value=10.0), min_size=30, max_size=30),
    shift=st.floats(min_value=-100.0, max_value=100.0),
    scale=st.floats(min_value=0.01, max_value=100.0),
)
def test_time_mean_is_a_weighted_average(
    x: list[float], gaps: list[float], shift: float, scale: float
) -> None:
    xs = np.array(x)
    t = np.concatenate([[0.0], np.cumsum(gaps[: len(x) - 1])])
    m = time_mean(xs, t)
    assert xs.min() - 1e-9 <= m <= xs.max() + 1e-9
    # invariant under shifting and rescaling time
    assert time_mean(xs, shift + scale * t) == pytest.approx(m, rel=1e-6, abs=1e-6)
    # a constant averages to itself
    assert time_mean(np.full_like(xs, 3.25), t) == pytest.approx(3.25)


def test_pause_and_filler_shares_of_the_speech_time(tmp_path: Path) -> None:
    said = (
        Utterance("intro", "hello", 0.0, 3.0),
        Utterance("wait", "", 3.0, 5.0, length=1.8),  # a pause vertex
        Utterance("okay", "Okay.", 5.5, 6.0, filler=True),
        Utterance("done", "bye", 6.5, 8.0),
    )
    log = hand_log(utterances=said)
    row = episode_metrics(log)
    # speech 0-8 s: clips 3 + 0.5 + 1.5 = 5 s, silence 3 s, filler 0.5 s
    assert row["pause_share"] == pytest.approx(3.0 / 8.0)
    assert row["filler_share"] == pytest.approx(0.5 / 8.0)
    # content over the motion (0-6 s): 'intro' 0-3 s and 'done' from 6.5 s (after the motion);
    # the pause vertex and the filler are not content
    assert row["content_share"] == pytest.approx(3.0 / 6.0)
    assert list(row) == list(METRIC_COLUMNS)
    back = EpisodeLog.load_npz(log.save_npz(tmp_path / "x.npz"))
    assert back.utterances == said and back.utterances[1].is_pause
    # the hand log's default speech: 3 s + 4.5 s of clips, no filler
    plain = episode_metrics(hand_log())
    assert plain["pause_share"] == pytest.approx(0.5 / 8.0)
    assert plain["filler_share"] == 0.0
    # 'intro' 0-3 s and 'done' 3.5-6 s of its 3.5-8 s heard while the motion lasts (0-6 s)
    assert plain["content_share"] == pytest.approx(5.5 / 6.0)
    with pytest.raises(ConfigError, match=r"Utterance\.length must be finite and >= 0"):
        Utterance("wait", "", 3.0, 5.0, length=-1.0)
