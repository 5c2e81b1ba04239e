"""Phrase audio: eSpeak NG synthesis, disk/memory cache, recorded clips, errors."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import soundfile as sf

from langenv.errors import AudioError, ConfigError
from langenv.speech.audio import ClipLibrary, default_cache_dir, trim_silence
from langenv.speech.phrase import Phrase

DONE = "And you're done."


def tone(sr: int, seconds: float, lead: float = 0.0, tail: float = 0.0) -> np.ndarray:
    t = np.arange(int(seconds * sr)) / sr
    y = 0.4 * np.sin(2 * np.pi * 330.0 * t)
    return np.concatenate([np.zeros(int(lead * sr)), y, np.zeros(int(tail * sr))])


def test_tts_clip_is_mono_float32_trimmed_speech(tmp_path: Path) -> None:
    lib = ClipLibrary(cache_dir=tmp_path)
    y = lib.synthesize(DONE)
    assert y.dtype == np.float32 and y.ndim == 1
    assert not y.flags.writeable
    d = y.size / lib.sr
    assert 0.4 < d < 2.0  # three short words
    assert 0.05 < float(np.max(np.abs(y))) <= 1.0
    edge = int(0.03 * lib.sr)
    peak = float(np.max(np.abs(y)))
    assert np.max(np.abs(y[:edge])) > 1e-3 * peak  # no leading silence left
    assert np.max(np.abs(y[-edge:])) > 1e-3 * peak  # no trailing silence left


def test_slower_rate_gives_longer_clip(tmp_path: Path) -> None:
    text = "Glide like you are ice skating on this table."
    slow = ClipLibrary(cache_dir=tmp_path, rate=110).synthesize(text)
    fast = ClipLibrary(cache_dir=tmp_path, rate=220).synthesize(text)
    assert slow.size > 1.5 * fast.size


def test_disk_cache_is_keyed_by_text_and_voice_settings(tmp_path: Path) -> None:
    a = ClipLibrary(cache_dir=tmp_path)
    y1 = a.synthesize(DONE)
    assert a.synthesize(DONE) is y1  # memory cache
    assert len(list(tmp_path.glob("*.npy"))) == 1
    b = ClipLibrary(cache_dir=tmp_path)  # a fresh library reads the disk cache
    np.testing.assert_array_equal(b.synthesize(DONE), y1)
    assert len(list(tmp_path.glob("*.npy"))) == 1
    ClipLibrary(cache_dir=tmp_path, rate=170).synthesize(DONE)
    ClipLibrary(cache_dir=tmp_path).synthesize("Slide, slide, slide.")
    assert len(list(tmp_path.glob("*.npy"))) == 3
    # a corrupt cache entry is ignored and rewritten with the same clip (a clip is a pure
    # function of its text and settings, not of what the cache held)
    for f in tmp_path.glob("*.npy"):
        f.write_bytes(b"garbage")
    np.testing.assert_array_equal(ClipLibrary(cache_dir=tmp_path).synthesize(DONE), y1)


def test_default_cache_dir_follows_environment(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("LANGCTRL_CACHE", str(tmp_path / "c"))
    assert default_cache_dir() == tmp_path / "c"
    ClipLibrary().synthesize("One more good one.")
    assert len(list((tmp_path / "c").glob("*.npy"))) == 1
    monkeypatch.delenv("LANGCTRL_CACHE")
    assert default_cache_dir() == Path.home() / ".cache" / "langctrl" / "tts"


def test_no_disk_cache_writes_nothing(tmp_path: Path) -> None:
    lib = ClipLibrary(cache_dir=tmp_path / "c", disk_cache=False)
    assert lib.synthesize(DONE).size > 0
    assert not (tmp_path / "c").exists()


def test_unwritable_cache_warns_and_still_synthesises(tmp_path: Path) -> None:
    blocker = tmp_path / "file"
    blocker.write_text("not a directory")
    lib = ClipLibrary(cache_dir=blocker / "sub")
    with pytest.warns(RuntimeWarning, match="not writable"):
        y = lib.synthesize(DONE)
    assert y.size > 0


def test_resampled_tts_has_the_same_duration(tmp_path: Path) -> None:
    y22 = ClipLibrary(cache_dir=tmp_path).synthesize(DONE)
    y16 = ClipLibrary(16000, cache_dir=tmp_path).synthesize(DONE)
    assert y16.size / 16000 == pytest.approx(y22.size / 22050, abs=2e-3)


@pytest.mark.parametrize(("sr", "channels", "fmt"), [(44100, 2, "wav"), (16000, 1, "flac")])
def test_recorded_clip_is_mixed_resampled_and_trimmed(
    tmp_path: Path, sr: int, channels: int, fmt: str
) -> None:
    y = tone(sr, 1.0, lead=0.3, tail=0.5)
    data = np.stack([y, 0.5 * y], axis=1) if channels == 2 else y
    path = tmp_path / f"clip.{fmt}"
    sf.write(path, data, sr)
    lib = ClipLibrary(cache_dir=tmp_path)
    clip = lib.clip(Phrase("hello", None, path))
    assert clip.dtype == np.float32 and clip.ndim == 1
    assert 0.99 <= clip.size / lib.sr <= 1.05
    expected = 0.4 * (0.75 if channels == 2 else 1.0)
    assert float(np.max(np.abs(clip))) == pytest.approx(expected, rel=0.05)
    assert lib.duration(Phrase("hello", None, path)) == clip.size / lib.sr
    untrimmed = ClipLibrary(cache_dir=tmp_path, trim_db=None).load_file(path)
    assert untrimmed.size / 22050 == pytest.approx(1.8, abs=0.01)


def test_audio_file_wins_over_text(tmp_path: Path) -> None:
    path = tmp_path / "c.wav"
    sf.write(path, tone(22050, 0.5), 22050)
    lib = ClipLibrary(cache_dir=tmp_path)
    clip = lib.clip(Phrase("p", "a long text that would take several seconds to say", path))
    assert clip.size / lib.sr == pytest.approx(0.5, abs=0.03)


def test_missing_file_names_file_and_phrase(tmp_path: Path) -> None:
    lib = ClipLibrary(cache_dir=tmp_path)
    with pytest.raises(AudioError) as info:
        lib.clip(Phrase("intro", None, tmp_path / "nope.wav"))
    assert "nope.wav" in str(info.value) and "'intro'" in str(info.value)


def test_unreadable_and_silent_files_raise(tmp_path: Path) -> None:
    lib = ClipLibrary(cache_dir=tmp_path)
    bad = tmp_path / "bad.wav"
    bad.write_bytes(b"RIFF....WAVEfmt garbage")
    with pytest.raises(AudioError, match=r"bad\.wav.*'p'"):
        lib.load_file(bad, phrase="p")
    silent = tmp_path / "silent.wav"
    sf.write(silent, np.zeros(22050), 22050)
    with pytest.raises(AudioError, match="silent"):
        lib.load_file(silent)


@pytest.mark.parametrize(
    "kwargs",
    [{"sr": 100}, {"sr": 22050.0}, {"rate": 10}, {"pitch": 101}, {"voice": ""}, {"trim_db": -3}],
)
def test_bad_arguments_raise_config_error(kwargs: dict[str, object]) -> None:
    name = next(iter(kwargs))
    with pytest.raises(ConfigError, match=name):
        ClipLibrary(**kwargs)  # type: ignore[arg-type]


def test_unknown_voice_raises(tmp_path: Path) -> None:
    with pytest.raises(AudioError, match="no voice"):
        ClipLibrary(cache_dir=tmp_path, voice="xx-nonexistent").synthesize(DONE)


def test_trim_silence_keeps_the_sound() -> None:
    sr = 8000
    y = tone(sr, 0.5, lead=0.2, tail=0.3)
    z = trim_silence(y, sr)
    assert 0.5 - 2 / sr <= z.size / sr <= 0.5 + 2 / sr  # to the sample (sin starts at 0)
    assert trim_silence(np.zeros(sr), sr).size == 0
